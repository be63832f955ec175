"""The compiled core's records and structure: a tableau added as data alone, the envelope solve, the workspace."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import build_scene, simulate
from wearbench.model import integrators as I
from wearbench.model import kernel as K
from wearbench.model.methods import Dopri5, Method, Tableau

# Bogacki-Shampine 3(2) (J. Appl. Math. Lett. 2, 1989), FSAL, four stages: nothing but data
BS3 = Tableau("bs3", 3, c=(0.0, 1 / 2, 3 / 4, 1.0), a=((), (1 / 2,), (0.0, 3 / 4), (2 / 9, 1 / 3, 4 / 9)),
              b=(2 / 9, 1 / 3, 4 / 9, 0.0), e=(2 / 9 - 7 / 24, 1 / 3 - 1 / 4, 4 / 9 - 1 / 3, -1 / 8), fsal=True,
              error_order=2, reference="Bogacki, Shampine 1989")


def test_a_tableau_with_another_stage_count_is_data_alone(pendulum_bench):
    scene = build_scene(pendulum_bench)
    ref = simulate(scene, t_end=1.0, output_rate=10, method="dopri5", rtol=1e-12, atol=1e-15)
    fixed = Method("bs3-fixed", BS3, adaptive=False, project=False)
    errs = []
    for h in (0.02, 0.01, 0.005):
        r = simulate(scene, t_end=1.0, output_rate=10, method=fixed, step=h)
        errs.append(np.abs(r.table[["O_fx", "O_fy"]] - ref.table[["O_fx", "O_fy"]]).to_numpy().max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 2.6) & (orders < 3.5)), orders  # third order
    # adaptive with its own embedded estimate and controller exponents: meets the tolerance
    adaptive = dataclasses.replace(Dopri5, name="bs3", tableau=BS3)
    a = simulate(scene, t_end=1.0, output_rate=10, method=adaptive, rtol=1e-7, atol=1e-10)
    scale = np.abs(ref.table["O_fy"]).max()
    assert np.abs(a.table["O_fy"] - ref.table["O_fy"]).max() < 1e-4 * scale
    assert a.summary["rejected_steps"] < a.summary["steps"]
    assert BS3.scheme().end == 3 and BS3.scheme().a.shape == (4, 4)


def test_a_tableau_that_is_not_explicit_or_not_fsal_is_refused():
    with pytest.raises(ValueError, match="explicit"):
        Tableau("bad", 2, c=(0.0, 1.0), a=((), (0.5, 0.5)), b=(0.5, 0.5))
    with pytest.raises(ValueError, match="FSAL"):
        Tableau("bad", 2, c=(0.0, 1.0), a=((), (1.0,)), b=(0.5, 0.5), fsal=True)


def _pattern_spd(P, rng):
    """A random symmetric positive definite matrix with the sparsity of the scene's S = Phi_q M^-1 Phi_q^T."""
    m = P.jb.shape[0]
    Jv = rng.standard_normal((m, 2, 3))
    S = np.zeros((m, m))
    K._schur(P, Jv, S)
    return S + 1e-3 * np.eye(m)


def test_envelope_cholesky_is_the_dense_factorisation_bit_for_bit():
    scene = build_scene(load_bench(shipped_bench("ninebar-testbed")))
    P = scene.params
    m = P.jb.shape[0]
    first = P.s_first
    assert first.tolist() != [0] * m and np.all(first <= np.arange(m))
    rng = np.random.default_rng(3)
    for _ in range(20):
        S = _pattern_spd(P, rng)
        assert all(not S[i, :first[i]].any() for i in range(m))  # nothing left of the envelope
        rhs = rng.standard_normal(m)
        x_env, x_dense = np.zeros(m), np.zeros(m)
        assert K._cholesky_solve(S.copy(), rhs, x_env, first) == K.OK
        assert K._cholesky_solve(S.copy(), rhs, x_dense, np.zeros(m, np.int64)) == K.OK
        assert np.array_equal(x_env, x_dense)
        np.testing.assert_allclose(x_env, np.linalg.solve(S, rhs), rtol=1e-8, atol=1e-12)


def test_the_workspace_is_one_record_the_kernels_fill():
    scene = build_scene(load_bench(shipped_bench("slider-crank")))
    W = scene.work()
    assert isinstance(W, K.Workspace)
    assert W.S.shape == (scene.m, scene.m) and W.cs.shape == (scene.n // 3,)
    K.constraints(0.0, scene.q0.copy(), scene.v_unit * 10.0, 10.0, scene.params, W)
    assert np.abs(W.phi).max() < 1e-9  # assembled
    stats = I.new_stats()
    assert stats.dtype == I.STATS and stats[0]["steps"] == 0
    res = simulate(scene, revolutions=0.05)
    assert res.summary["function_evaluations"] >= 6 * (res.summary["steps"] + res.summary["rejected_steps"]) > 0
