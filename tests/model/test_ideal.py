"""Ideal-joint scenes: kinematics against closed forms, dynamics against kinematics, RK4 order."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.bench.schema import BenchError
from wearbench.model import SimulationError, Spring, Torque, build_scene, simulate
from wearbench.model.methods import RK4Paper


def test_ideal_slider_crank_matches_closed_form(slider_crank):
    scene = build_scene(slider_crank, clearances={"S": None})
    assert scene.dof == 0 and "kinematics" in scene.description
    res = simulate(scene, revolutions=1.0)
    t = res.table["t"].to_numpy()
    w = slider_crank.speed
    r, l = 0.05, 0.12
    th = w * t
    s, c = np.sin(th), np.cos(th)
    root = np.sqrt(l**2 - r**2 * s**2)
    x = r * c + root
    dx = -r * s - r**2 * s * c / root
    ddx = -r * c - r**2 * (c**2 - s**2) / root - r**4 * s**2 * c**2 / root**3
    np.testing.assert_allclose(res.table["slider_pos"], x, atol=1e-9)
    np.testing.assert_allclose(res.table["slider_vel"], w * dx, atol=1e-6 * abs(w) * r)
    np.testing.assert_allclose(res.table["slider_acc"], w**2 * ddx, atol=1e-6 * w**2 * r)


def test_ideal_ninebar_dynamics_agrees_with_kinematics_and_inverse_dynamics(ninebar):
    scene = build_scene(ninebar, clearances={"A": None, "B": None})
    full = simulate(scene, revolutions=1.0, output_rate=5000)
    assert full.summary["method"] == "kinematics"
    assert full.summary["peak_slider_acc"] == pytest.approx(51, rel=0.05)  # parameters note: ~51 m/s^2
    kin = simulate(scene, t_end=0.1, output_rate=5000)
    dyn = simulate(scene, t_end=0.1, output_rate=5000, method="dopri5", rtol=1e-9, atol=1e-12)
    scale = np.abs(kin.table["slider_acc"]).max()
    np.testing.assert_allclose(dyn.table["slider_acc"], kin.table["slider_acc"], atol=1e-4 * scale)
    np.testing.assert_allclose(dyn.table["slider_pos"], kin.table["slider_pos"], atol=1e-8)
    for col in ("A_fx", "A_fy", "C_rod3_fx", "D_link8_fy", "E_fx", "O4_fy"):
        ref = kin.table[col].to_numpy()
        np.testing.assert_allclose(dyn.table[col], ref, atol=1e-4 * np.abs(ref).max())


def test_joint_reactions_balance_a_static_pendulum(pendulum_bench):
    # released horizontal: at t = 0 the pin carries m g (1 - 3/4) upwards (rigid-body closed form)
    scene = build_scene(pendulum_bench)
    assert scene.dof == 1
    res = simulate(scene, t_end=1e-3, output_rate=1e4, rtol=1e-10, atol=1e-13)
    assert res.table["O_fy"].iloc[0] == pytest.approx(9.81 * 0.25, rel=1e-6)


def test_rk4_converges_with_fourth_order(pendulum_bench):
    scene = build_scene(pendulum_bench)
    rk4 = dataclasses.replace(RK4Paper, baumgarte=(0.0, 0.0), project=False)
    ref = simulate(scene, t_end=1.0, output_rate=10, method="dopri5", rtol=1e-12, atol=1e-15)
    errs = []
    for h in (0.02, 0.01, 0.005):
        r = simulate(scene, t_end=1.0, output_rate=10, method=rk4, step=h)
        errs.append(np.abs(r.table[["O_fx", "O_fy"]] - ref.table[["O_fx", "O_fy"]]).to_numpy().max())
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((orders > 3.5) & (orders < 4.6)), orders


@pytest.mark.parametrize("name", ["fourbar", "slider-crank", "ninebar-testbed"])
def test_shipped_scenes_build_from_their_files(name):
    bench = load_bench(shipped_bench(name))
    scene = build_scene(bench)
    assert scene.dof == 2 * len(bench.clearance_joints)
    ideal = build_scene(bench, clearances={j.name: None for j in bench.clearance_joints})
    res = simulate(ideal, revolutions=1.0, output_rate=2000)
    # closed loop: the ideal mechanism returns to its start after one revolution
    assert res.table["slider_pos"].iloc[-1] == pytest.approx(res.table["slider_pos"].iloc[0], abs=1e-9)


def test_mechanism_that_does_not_assemble_raises_bench_error():
    text = shipped_bench("fourbar").read_text().replace('length = "0.30 m"\nmass = "0.7065 kg"',
                                                        'length = "0.05 m"\nmass = "0.7065 kg"', 1)
    bench = parse_bench(text, "broken-fourbar.toml")
    with pytest.raises(BenchError, match="does not assemble") as info:
        build_scene(bench)
    assert info.value.key == "assembly"
    assert info.value.value in {"P", "R", "Q", "O"}
    assert "broken-fourbar.toml" in str(info.value)


def test_driving_through_a_dead_point_raises_simulation_error():
    # a non-Grashof four-bar (crank 0.28 m): the crank cannot turn round, kinematics must stop there
    text = (shipped_bench("fourbar").read_text()
            .replace('length = "0.10 m"\nmass = "0.2355 kg"', 'length = "0.28 m"\nmass = "0.2355 kg"', 1)
            .replace('P = ["0 m", "0.10 m"]', 'P = ["0 m", "0.28 m"]'))
    scene = build_scene(parse_bench(text, "non-grashof.toml"), clearances={"R": None})
    with pytest.raises(SimulationError) as info:
        simulate(scene, revolutions=1.0)
    err = info.value
    assert 0.1 < err.t < 0.2 and "t = " in str(err)
    assert err.joint and set(err.joint.split(", ")) <= {"O", "P", "R", "Q"}
    assert err.state["q"]["crank"]


def test_speed_profile_drives_the_crank_through_the_integrated_angle(slider_crank):
    # motor ramped from rest at 2000 rad/s^2: theta = phase + a t^2 / 2 (exact for a linear speed)
    scene = build_scene(slider_crank, clearances={"S": None})
    a = 2000.0
    res = simulate(scene, t_end=0.05, output_rate=2e4, speed=lambda t: a * t)
    t = res.table["t"].to_numpy()
    np.testing.assert_allclose(res.table["theta_O"], 0.5 * a * t**2, atol=1e-9)
    th, w, al = 0.5 * a * t**2, a * t, a
    r, l = 0.05, 0.12
    s, c = np.sin(th), np.cos(th)
    root = np.sqrt(l**2 - r**2 * s**2)
    dx = -r * s - r**2 * s * c / root
    ddx = -r * c - r**2 * (c**2 - s**2) / root - r**4 * s**2 * c**2 / root**3
    np.testing.assert_allclose(res.table["slider_pos"], r * c + root, atol=1e-9)
    np.testing.assert_allclose(res.table["slider_acc"], ddx * w**2 + dx * al, atol=1e-6 * np.abs(ddx * w**2).max())
    # the same profile as arrays (times, speeds): linear in between, the same samples
    times = np.arange(0.0, 0.06, 1e-4)
    tabled = simulate(scene, t_end=0.05, output_rate=2e4, speed=(times, a * times))
    np.testing.assert_array_equal(tabled.table["theta_O"], res.table["theta_O"])
    with pytest.raises(ValueError, match="t_end"):
        simulate(scene, speed=lambda t: a * t)


def test_spring_damper_and_torque_elements(pendulum_bench):
    # bar pinned at O, tip spring to T straight above the tip: small swings at w = sqrt(3 k / m)
    no_gravity = dataclasses.replace(pendulum_bench, gravity=(0.0, 0.0))
    k, c = 100.0, 0.5
    scene = build_scene(no_gravity, forces=[Spring("bar", "end", "frame", "T", stiffness=k, damping=c)])
    v = np.array([0.0, 0.5e-3, 1e-3])  # rigid rotation at 1 mrad/s about O
    res = simulate(scene, t_end=2.0, output_rate=2000, initial=(scene.q0, v), rtol=1e-10, atol=1e-13)
    fy = res.table["O_fy"].to_numpy()
    t = res.table["t"].to_numpy()
    up = np.flatnonzero((fy[:-1] < 0) & (fy[1:] >= 0))
    period = np.mean(np.diff(t[up]))
    wd = np.sqrt(3 * k / 1.0 - (1.5 * c) ** 2)  # damped: zeta w = c L^2 / (2 I_O) = 1.5 c
    assert period == pytest.approx(2 * np.pi / wd, rel=2e-3)
    peaks = np.abs(fy[: len(fy) // 4]).max(), np.abs(fy[-len(fy) // 4:]).max()
    assert peaks[1] / peaks[0] == pytest.approx(np.exp(-1.5 * c * 1.5), rel=0.1)
    # a torque balancing gravity holds the released bar still: the pin carries the full weight
    held = build_scene(pendulum_bench, forces=[Torque("bar", torque=9.81 * 0.5)])
    r = simulate(held, t_end=0.1, output_rate=100)
    np.testing.assert_allclose(r.table["O_fy"], 9.81, rtol=1e-6)  # force on the bar, upwards
