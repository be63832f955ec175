"""The compiled core's records and structure: a tableau added as data alone, the envelope solve, the workspace."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import build_scene, simulate
from wearbench.model import integrators as I
from wearbench.model import kernel as K
from wearbench.model.methods import DOPRI5, Dopri5, Method, Tableau

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
    K.schur(P, Jv, S)  # the lower triangle, all the factorisation reads
    return np.tril(S) + np.tril(S, -1).T + 1e-3 * np.eye(m)


def test_schur_complement_is_the_dense_product_in_its_lower_triangle():
    from wearbench.model.scene import dense_jacobian

    scene = build_scene(load_bench(shipped_bench("ninebar-testbed")))
    P = scene.params
    W = scene.work()
    K.constraints(0.0, scene.q0.copy(), scene.v_unit * 10.0, 10.0, P, W)
    J = dense_jacobian(P, W.Jv, scene.n)
    S = np.full((scene.m, scene.m), np.nan)  # stale values in the envelope are overwritten, nothing else read
    K.schur(P, W.Jv, S)
    dense = J @ np.diag(P.minv) @ J.T
    low = np.tril(np.ones_like(S, dtype=bool)) & (np.arange(scene.m)[None, :] >= P.s_first[:, None])
    np.testing.assert_allclose(S[low], dense[low], rtol=1e-12, atol=1e-12 * np.abs(dense).max())
    assert not dense[~low & (np.arange(scene.m)[None, :] <= np.arange(scene.m)[:, None])].any()  # envelope


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
        assert K.cholesky_solve(S.copy(), rhs, x_env, first) == K.OK
        assert K.cholesky_solve(S.copy(), rhs, x_dense, np.zeros(m, np.int64)) == K.OK
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


def _dense(scheme, theta):
    """b_i(theta) and b_i'(theta) of a scheme's continuous extension."""
    powers = np.arange(1, scheme.d.shape[1] + 1)
    return scheme.d @ theta ** powers, scheme.d @ (powers * theta ** (powers - 1))


def test_dopri5_continuous_extension_is_fourth_order_and_its_derivative_third():
    # y' = -y from y = 1: the dense output against exp(-t) inside one step (local errors h^5 and h^4)
    s = DOPRI5.scheme()
    errs, derrs = [], []
    for h in (0.2, 0.1, 0.05):
        k = np.zeros(s.stages)
        for i in range(s.stages):
            k[i] = -(1.0 + h * s.a[i, :i] @ k[:i])
        b, db = _dense(s, 0.37)
        errs.append(abs(1.0 + h * b @ k - np.exp(-0.37 * h)))
        derrs.append(abs(db @ k + np.exp(-0.37 * h)))
    order = np.log2(np.array(errs[:-1]) / errs[1:])
    dorder = np.log2(np.array(derrs[:-1]) / derrs[1:])
    assert np.all(order > 4.7) and np.all(dorder > 3.7), (order, dorder)
    b1, _ = _dense(s, 1.0)
    np.testing.assert_allclose(b1, DOPRI5.b, atol=1e-15)  # theta = 1 is the step's own solution
    with pytest.raises(ValueError, match="continuous extension"):
        dataclasses.replace(DOPRI5, dense=DOPRI5.dense[:-1])


def test_table_samples_from_the_continuous_extension_match_evaluated_ones():
    # Flores' slider-crank with its clearance joint: the samples' accelerations, reactions and contact
    # columns from the stages (default) against a right-hand side at each interpolated state; the
    # trajectory (steps) is the same, only the table differs
    scene = build_scene(load_bench(shipped_bench("slider-crank")))
    fast = simulate(scene, revolutions=0.3)
    slow = simulate(scene, revolutions=0.3, evaluate_samples=True)
    assert np.array_equal(fast.final[0], slow.final[0]) and fast.summary["steps"] == slow.summary["steps"]
    assert fast.summary["function_evaluations"] < slow.summary["function_evaluations"] - len(fast.table) // 2
    a, b = fast.table, slow.table
    np.testing.assert_allclose(a["slider_pos"], b["slider_pos"], atol=1e-8)
    acc = b["slider_acc"].to_numpy()
    err = a["slider_acc"].to_numpy() - acc
    assert np.sqrt(np.mean(err ** 2)) < 0.02 * np.sqrt(np.mean(acc ** 2))
    assert a["slider_acc"].abs().max() == pytest.approx(b["slider_acc"].abs().max(), rel=0.02)
    (j,) = scene.clearance_joints
    np.testing.assert_allclose(a[f"{j}_pen"], b[f"{j}_pen"], atol=0.01 * b[f"{j}_pen"].max())  # 4th-order vs cubic
    assert a[f"{j}_fn"].max() == pytest.approx(b[f"{j}_fn"].max(), rel=0.02)
    ref = b[[c for c in b if c.endswith(("_fx", "_fy"))]].to_numpy()
    got = a[[c for c in b if c.endswith(("_fx", "_fy"))]].to_numpy()
    assert np.sqrt(np.mean((got - ref) ** 2)) < 0.02 * np.sqrt(np.mean(ref ** 2))


def test_point_along_is_the_derivative_of_its_own_position():
    # a body spinning up and sliding: velocity and acceleration against central differences of position
    t = np.linspace(0.0, 1.0, 20001)
    dt = t[1] - t[0]
    x, y, th = 0.3 * t ** 2, np.sin(2 * t), 1.5 * t + 2.0 * t ** 3
    vx, vy, w = 0.6 * t, 2 * np.cos(2 * t), 1.5 + 6.0 * t ** 2
    ax, ay, al = 0.6 + 0 * t, -4 * np.sin(2 * t), 12.0 * t
    pos, vel, acc = K.point_along(x, y, th, vx, vy, w, ax, ay, al, 0.07, -0.02, 0.4)
    # the point in the plane, differentiated numerically, projected on the (turning) measuring axis
    px, py = x + np.cos(th) * 0.07 + np.sin(th) * 0.02, y + np.sin(th) * 0.07 - np.cos(th) * 0.02
    ux, uy = np.cos(th + 0.4), np.sin(th + 0.4)
    np.testing.assert_allclose(pos, px * ux + py * uy, atol=1e-15)
    dvx, dvy = np.gradient(px, dt), np.gradient(py, dt)
    ddx, ddy = np.gradient(dvx, dt), np.gradient(dvy, dt)
    np.testing.assert_allclose(vel[2:-2], (dvx * ux + dvy * uy)[2:-2], atol=1e-6)
    np.testing.assert_allclose(acc[2:-2], (ddx * ux + ddy * uy)[2:-2], atol=1e-4)
    one = K.point_along(x[7], y[7], th[7], vx[7], vy[7], w[7], ax[7], ay[7], al[7], 0.07, -0.02, 0.4)
    assert one == pytest.approx((pos[7], vel[7], acc[7]), rel=1e-14)


def test_kinematics_is_a_registered_method(slider_crank):
    from wearbench.model.methods import METHODS, get_method

    assert get_method("kinematics") is METHODS["kinematics"] and METHODS["kinematics"].tableau is None
    scene = build_scene(slider_crank, clearances={"S": None})
    res = simulate(scene, revolutions=0.2, method="kinematics")
    assert res.summary["method"] == "kinematics" and res.summary["steps"] == len(res.table)
    with pytest.raises(ValueError, match="fully driven"):
        simulate(build_scene(slider_crank), revolutions=0.2, method="kinematics")
