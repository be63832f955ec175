"""Method "imex" (linearly implicit extrapolation, contact force implicit): its solve, order and impacts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.model import build_scene, simulate
from wearbench.model import implicit_contact as IC
from wearbench.model import integrators as I
from wearbench.model import kernel as K
from wearbench.model.methods import DOPRI5, METHODS, Extrapolation, get_method
from wearbench.model.realisation import state_scene

from .conftest import disc_bench

HERTZ_DURATION = 2.9432  # contact time x impact speed / largest penetration, Hertz impact (Johnson 1985, 11.4)


def _impact(law: str, ce: float, method: str = "imex", v_in: float = 0.2):
    scene = build_scene(disc_bench(law=law, ce=ce))
    res = simulate(scene, t_end=0.0035, output_rate=1e6, method=method, rtol=1e-8, atol=1e-11,
                   initial=(np.zeros(3), np.array([v_in, 0.0, 0.0])))
    return scene, res


def test_elastic_impact_matches_hertz():
    """Frictionless elastic disc impact (1 kg, 0.2 m/s): largest penetration (5 m v^2 / 4 K)^(2/5),
    contact time 2.9432 pen_max / v, rebound at the incoming speed."""
    scene, res = _impact("lankarani-nikravesh", 1.0)
    k = scene.clearance_params("J")["stiffness"]
    pen_max = (5 * 1.0 * 0.2 ** 2 / (4 * k)) ** 0.4
    pen = res.table["J_pen"].to_numpy()
    t = res.table["t"].to_numpy()
    assert pen.max() == pytest.approx(pen_max, rel=2e-3)
    touching = t[pen > 0]
    assert touching[-1] - touching[0] == pytest.approx(HERTZ_DURATION * pen_max / 0.2, rel=0.02)
    vx = np.gradient(res.table["J_ex"], t)
    assert -vx[-10:].mean() == pytest.approx(0.2, rel=1e-3)


@pytest.mark.parametrize("law,ce,rel", [("flores", 0.3, 0.2), ("flores", 0.8, 0.06),
                                        ("lankarani-nikravesh", 0.9, 0.03)])
def test_damped_impact_restores_the_coefficient_of_restitution_and_agrees_with_the_default(law, ce, rel):
    _, res = _impact(law, ce)
    _, ref = _impact(law, ce, method="default")
    t = res.table["t"].to_numpy()
    v_out = -np.gradient(res.table["J_ex"], t)[-10:].mean()
    v_ref = -np.gradient(ref.table["J_ex"], t)[-10:].mean()
    assert v_out / 0.2 == pytest.approx(ce, rel=rel)  # the laws' own accuracy (as test_clearance)
    assert v_out == pytest.approx(v_ref, rel=1e-4)  # the same motion as DOPRI5 at this tolerance
    assert res.summary["peak_fn"]["J"] == pytest.approx(ref.summary["peak_fn"]["J"], rel=1e-4)


def _testbed_contact_state():
    """The test bed (0.3 mm, new) at a table sample where joint A is in contact, with its contact mode set."""
    bench = load_bench(shipped_bench("ninebar-testbed"))
    scene = state_scene(bench, {s.name: s for s in bench.states}["0.3 mm new"])
    res = simulate(scene, t_end=0.02)
    t0 = float(res.table["t"].to_numpy()[np.flatnonzero(res.table["A_pen"].to_numpy() > 0)[1]])
    q, v = simulate(scene, t_end=t0).final
    y = np.concatenate([q, v])
    nc, n, m = 2, scene.n, scene.m
    inc, v0i = np.zeros(nc, np.int64), np.zeros(nc)
    f, lam, cout = np.zeros(2 * n), np.zeros(m), np.zeros((nc, K.NCO))
    I.deriv(t0, y, bench.speed, scene.params, 0.0, 0.0, inc, v0i, f, lam, cout, scene.work())
    for c in range(nc):
        if cout[c, K.CO_PEN] > 0:
            inc[c], v0i[c] = 1, max(1e-3, abs(cout[c, K.CO_VN]))
    assert inc[0] == 1
    return scene, bench.speed, t0, y, inc, v0i


def test_substep_solve_is_the_dense_linearly_implicit_solve():
    """(I - h J) dy = h f solved through the joints' two-unknown systems equals the dense solve with J
    assembled from the same G, U, Kp, Kv, and U maps into the constraints' null space."""
    scene, speed, t0, y, inc, v0i = _testbed_contact_state()
    P, W, n, m, nc = scene.params, scene.work(), scene.n, scene.m, 2
    f, lam, cout = np.zeros(2 * n), np.zeros(m), np.zeros((nc, K.NCO))
    I.deriv(t0, y, speed, P, 0.0, 0.0, inc, v0i, f, lam, cout, W)
    X = IC.work(2 * n, m, nc, 4)
    IC.contact_jacobian(y[:n], P, inc, v0i, cout, W, X)
    IC._stiffness(P, X)
    G = np.zeros((2 * nc, n))
    for c in range(nc):
        for side in range(2):
            b = P.clr_b[c, side]
            if b >= 0:
                G[2 * c:2 * c + 2, 3 * b:3 * b + 3] = X.G[c, :, side]
    Kp = np.zeros((2 * nc, 2 * nc))
    Kv = np.zeros_like(Kp)
    for c in range(nc):
        Kp[2 * c:2 * c + 2, 2 * c:2 * c + 2] = X.Kp[c]
        Kv[2 * c:2 * c + 2, 2 * c:2 * c + 2] = X.Kv[c]
    assert np.abs(Kp).max() > 1e7  # joint A in contact: a stiff Jacobian
    np.testing.assert_allclose(X.D, G @ X.U, atol=1e-12 * np.abs(X.D).max())
    I.deriv(t0, y, speed, P, 0.0, 0.0, inc, v0i, f, lam, cout, W)  # constraints at y in W
    phi_q = np.zeros((m, n))
    for r in range(m):
        for s in range(2):
            b = P.jb[r, s]
            if b >= 0:
                phi_q[r, 3 * b:3 * b + 3] = W.Jv[r, s]
    assert np.abs(phi_q @ X.U).max() < 1e-9 * np.abs(X.U).max()
    J = np.zeros((2 * n, 2 * n))
    J[:n, n:] = np.eye(n)
    J[n:, :n] = X.U @ Kp @ G
    J[n:, n:] = X.U @ Kv @ G
    for h in (1e-6, 1e-5, 1e-4):
        IC._small_matrix(X, h)
        yi = y.copy()
        IC._substep(P, X, h, f, yi)
        dense = np.linalg.solve(np.eye(2 * n) - h * J, h * f)
        np.testing.assert_allclose(yi - y, dense, rtol=0, atol=1e-9 * np.abs(dense).max())


def _dopri_reference(scene, speed, t0, y, inc, v0i, h, substeps=400):
    """y at t0 + h by DOPRI5 in fixed substeps (far more accurate than the steps tested)."""
    P, W, n, m = scene.params, scene.work(), scene.n, scene.m
    s = DOPRI5.scheme()
    k, lamk = np.zeros((s.end + 1, 2 * n)), np.zeros((s.end + 1, m))
    cnew, ynew, ytmp = np.zeros((2, K.NCO)), np.zeros(2 * n), np.zeros(2 * n)
    yy, tt, hs = y.copy(), t0, h / substeps
    atol = np.full(2 * n, 1e-9)
    for _ in range(substeps):
        I.deriv(tt, yy, speed, P, 0.0, 0.0, inc, v0i, k[0], lamk[0], cnew, W)
        I.erk_try(s, tt, yy, hs, k, speed, P, 0.0, 0.0, inc, v0i, ynew, ytmp, lamk, cnew, W, atol, 1e-6)
        yy, tt = ynew.copy(), tt + hs
    return yy


@pytest.mark.parametrize("columns", [2, 3, 4])
def test_local_error_in_contact_falls_at_the_extrapolation_order(columns):
    """One step inside a contact of the test bed: the local error falls as h^(columns + 1) (order
    ``columns``), for the exact contact Jacobian and for none at all (a W-method keeps its order for any
    Jacobian)."""
    scene, speed, t0, y, inc, v0i = _testbed_contact_state()
    P, W, n, m = scene.params, scene.work(), scene.n, scene.m
    hs = (2e-6, 1e-6, 5e-7) if columns > 2 else (1e-6, 5e-7, 2.5e-7)
    for exact in (True, False):
        errs = []
        for h in hs:
            ref = _dopri_reference(scene, speed, t0, y, inc, v0i, h)
            X = IC.work(2 * n, m, 2, columns)
            k, lamk = np.zeros((3, 2 * n)), np.zeros((3, m))
            cnew, ynew = np.zeros((2, K.NCO)), np.zeros(2 * n)
            I.deriv(t0, y, speed, P, 0.0, 0.0, inc, v0i, k[0], lamk[0], cnew, W)
            IC.contact_jacobian(y[:n], P, inc, v0i, cnew, W, X, exact)
            X.tj[0] = t0
            st, _, _ = IC.liex_try(columns, exact, t0, y, h, k, lamk, speed, P, inc, v0i, ynew, cnew, W, X,
                                   np.full(2 * n, 1e-30), 1e-30)
            assert st == 0
            errs.append(np.abs(ynew - ref)[n:].max())  # velocities: the contact force acts there first
        slopes = np.diff(np.log(errs)) / np.diff(np.log(hs))
        # beyond the order everywhere, near order + 1 on the finest pair (stiff: h |lambda| is 0.03-0.1 here)
        assert slopes.min() > columns and slopes[-1] > columns + 0.5, (exact, errs, slopes)


def test_agrees_with_the_tight_reference_over_the_predictable_start():
    """The test bed's first 15 ms (two contacts at A): imex at rtol 1e-6 tracks the tight reference as
    closely as the default does."""
    bench = load_bench(shipped_bench("ninebar-testbed"))
    scene = state_scene(bench, {s.name: s for s in bench.states}["0.3 mm new"])
    ref = simulate(scene, t_end=0.015, rtol=1e-10, atol=1e-13).table
    imex = simulate(scene, t_end=0.015, method="imex")
    assert (ref["A_pen"] > 0).any()
    for col, tol in (("A_pen", 1e-7), ("B_pen", 1e-7)):
        assert np.abs(imex.table[col] - ref[col]).max() < tol
    scale = np.sqrt(np.mean(ref["slider_acc"] ** 2))
    assert np.sqrt(np.mean((imex.table["slider_acc"] - ref["slider_acc"]) ** 2)) < 0.01 * scale


def test_method_registry():
    assert get_method("imex") is METHODS["imex"] and METHODS["imex"].tableau.columns == 4
    assert METHODS["default"].tableau is DOPRI5 and METHODS["default"].tableau.scheme().columns == 0
    with pytest.raises(ValueError, match="columns"):
        Extrapolation("one", 1)
    assert dataclasses.replace(METHODS["imex"], tableau=Extrapolation("x", 5)).tableau.scheme().columns == 5
