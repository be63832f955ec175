"""A peer's timing: Flores' slider-crank with one clearance joint in Exudyn and in wearbench, at equal error.

Exudyn (``pip install exudyn``, or ``pip install -e '.[peer]'``; C++ multibody, redundant coordinates)
has no revolute clearance joint: no element for a journal inside a bearing (its ``GeneralContact``
handles spheres, triangles and cables touching from outside, not a circle inside a circle), no
contact-mode state (the impact speed at contact onset the Lankarani-Nikravesh hysteresis damping
divides by) and a Cartesian connector's user function sees the markers' relative position and
velocity only, not the bodies' angular velocities the journal's friction needs. The closest case it
can express, run here in both codes, is the clearance joint as a Cartesian spring-damper between the
bearing's and the journal's centres whose force is a user function (Python): the Hertz contact
F = K d^1.5 along the line of centres for d = |e| - (R1 - R2) > 0, no damping, no friction. wearbench
runs the same bench with ``law = "hertz"`` and ``friction_coefficient = 0``.

Both codes start from wearbench's assembled state (journal centred, ideal velocities) and run one
crank revolution at 5000 rpm (12 ms). The error of a run is the relative RMS difference of the
slider velocity from a reference (wearbench, rtol 1e-11) on a common 20 kHz grid; the clearance
dynamics are chaotic: the error is taken over the predictability horizon, until two references
(rtol 1e-11 and 1e-10) first differ by 1e-4 of the RMS slider velocity.
Exudyn runs its default implicit solver (generalized-alpha, index 3, Newton; its explicit solvers
take no joint constraints) at fixed steps, wearbench its default DOPRI5 + projection at several
tolerances. The script prints each run's CPU time and error and, per error level, the ratio of the
CPU times of each code's cheapest run at least that accurate.

Run:  .venv/bin/python -m benchmarks.model.peer_exudyn [--repeat 2]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from wearbench.bench.load import load_bench, parse_bench, shipped_bench
from wearbench.model import build_scene, simulate

RATE = 20_000.0  # Hz, the comparison grid


def _hertz_bench():
    bench = load_bench(shipped_bench("slider-crank"))
    text = bench.source.replace('law = "lankarani-nikravesh"', 'law = "hertz"')
    text = text.replace("friction_coefficient = 0.01", "friction_coefficient = 0.0")
    if text == bench.source:
        raise RuntimeError("slider-crank.toml changed: cannot switch its contact to Hertz without friction")
    return parse_bench(text, bench.path)


def _wearbench(scene, t_end: float, rtol: float, repeat: int):
    best, res = math.inf, None
    for _ in range(repeat):
        t0 = time.process_time()
        res = simulate(scene, t_end=t_end, rtol=rtol, atol=rtol * 1e-3, output_rate=RATE)
        best = min(best, time.process_time() - t0)
    return best, res.table["t"].to_numpy(), res.table["slider_vel"].to_numpy()


def _exudyn_model(scene, bench, step: float, t_end: float):
    """Exudyn's slider-crank with the clearance joint as a Cartesian spring-damper user function:
    the system, its simulation settings and the slider-velocity sensor."""
    import exudyn as exu
    from exudyn.itemInterface import (
        CoordinateConstraint,
        Gravity,
        MarkerBodyMass,
        MarkerBodyPosition,
        MarkerBodyRigid,
        MarkerNodeCoordinate,
        NodePointGround,
        NodeRigidBody2D,
        ObjectConnectorCartesianSpringDamper,
        ObjectGround,
        ObjectRigidBody2D,
        PrismaticJoint2D,
        RevoluteJoint2D,
        SensorBody,
    )

    speed = bench.speed
    cp = scene.clearance_params("S")
    K, clear = float(cp["stiffness"]), float(cp["bearing_radius"] - cp["journal_radius"])
    q0, v0 = scene.q0, scene.v_unit * speed
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    nodes, objs = {}, {}
    for i, body in enumerate(bench.bodies):
        nodes[body.name] = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=list(q0[3 * i: 3 * i + 3]),
                                                       initialVelocities=list(v0[3 * i: 3 * i + 3])))
        objs[body.name] = mbs.AddObject(ObjectRigidBody2D(mass=body.mass, inertia=body.inertia,
                                                          nodeNumber=nodes[body.name]))
        mbs.AddLoad(Gravity(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=objs[body.name])),
                            loadVector=[*bench.gravity, 0.0]))

    def pos(name, point):
        x, y = bench.body(name).points[point]
        return mbs.AddMarker(MarkerBodyPosition(bodyNumber=objs[name], localPosition=[x, y, 0.0]))

    m_o = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0.0, 0.0, 0.0]))
    mbs.AddObject(RevoluteJoint2D(markerNumbers=[m_o, pos("crank", "start")]))
    mbs.AddObject(RevoluteJoint2D(markerNumbers=[pos("crank", "end"), pos("rod", "start")]))
    m_guide = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground, localPosition=[0.0, 0.0, 0.0]))
    m_slider = mbs.AddMarker(MarkerBodyRigid(bodyNumber=objs["slider"], localPosition=[0.0, 0.0, 0.0]))
    mbs.AddObject(PrismaticJoint2D(markerNumbers=[m_guide, m_slider], axisMarker0=[1.0, 0.0, 0.0],
                                   normalMarker1=[0.0, 1.0, 0.0], constrainRotation=True))
    m_gc = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=mbs.AddNode(NodePointGround()), coordinate=0))
    m_th = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes["crank"], coordinate=2))
    mbs.AddObject(CoordinateConstraint(markerNumbers=[m_gc, m_th], offset=speed, velocityLevel=True))

    def contact(mbs_, t, item, d, v, k, c, offset):  # force on the bearing's centre (marker 0)
        e = math.hypot(d[0], d[1])
        pen = e - clear
        if pen <= 0.0:
            return [0.0, 0.0, 0.0]
        f = K * pen ** 1.5 / e
        return [f * d[0], f * d[1], 0.0]

    mbs.AddObject(ObjectConnectorCartesianSpringDamper(markerNumbers=[pos("slider", "pin"), pos("rod", "end")],
                                                       springForceUserFunction=contact))
    sensor = mbs.AddSensor(SensorBody(bodyNumber=objs["slider"], storeInternal=True,
                                      outputVariableType=exu.OutputVariableType.Velocity))
    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.timeIntegration.endTime = t_end
    ss.timeIntegration.numberOfSteps = round(t_end / step)
    ss.timeIntegration.verboseMode = 0
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = 1.0 / RATE
    ss.timeIntegration.newton.useModifiedNewton = True
    ss.show.computationTime = False
    ss.show.statistics = False
    return mbs, ss, sensor


def _exudyn(scene, bench, t_end: float, step: float, repeat: int):
    """Best CPU time of ``repeat`` Exudyn runs at fixed ``step`` and the slider velocity (t, v)."""
    best, data = math.inf, None
    for _ in range(repeat):
        mbs, ss, sensor = _exudyn_model(scene, bench, step, t_end)
        t0 = time.process_time()
        mbs.SolveDynamic(ss)
        best = min(best, time.process_time() - t0)
        data = mbs.GetSensorStoredData(sensor)
    return best, data[:, 0], data[:, 1]


def _error(t, v, t_ref, v_ref) -> float:
    """Relative RMS difference of v from v_ref over the reference's grid (t_ref: the horizon)."""
    vi = np.interp(t_ref, t, v)
    return float(np.sqrt(np.mean((vi - v_ref) ** 2)) / np.sqrt(np.mean(v_ref ** 2)))


def _horizon(t_ref, v_ref, v_r2, level: float) -> int:
    """Samples until two references first differ by ``level`` times the RMS slider velocity."""
    bad = np.flatnonzero(np.abs(v_r2 - v_ref) > level * np.sqrt(np.mean(v_ref ** 2)))
    return int(bad[0]) if bad.size else t_ref.size


def _time_at(err_target: float, runs) -> float:
    """CPU time of the cheapest run [(time, error)] at least as accurate as ``err_target`` (nan if none)."""
    ok = [t for t, e in runs if e <= err_target]
    return min(ok) if ok else math.nan


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="timed runs per setting (best of)")
    args = ap.parse_args()
    import exudyn

    bench = _hertz_bench()
    scene = build_scene(bench)
    t_end = 2 * math.pi / bench.speed
    simulate(scene, t_end=1e-4)  # compile
    _, t_ref, v_ref = _wearbench(scene, t_end, 1e-11, 1)
    _, t_r2, v_r2 = _wearbench(scene, t_end, 1e-10, 1)
    whole = _error(t_r2, v_r2, t_ref, v_ref)
    n_h = _horizon(t_ref, v_ref, v_r2, 1e-4)
    t_ref, v_ref = t_ref[:n_h], v_ref[:n_h]
    floor = _error(t_r2, v_r2, t_ref, v_ref)
    print(f"slider-crank (Flores), clearance 0.5 mm at the slider pin, Hertz contact K = "
          f"{scene.clearance_params('S')['stiffness']:.3g} N/m^1.5, no damping or friction, {bench.speed:.1f} rad/s, "
          f"one revolution ({t_end * 1e3:.1f} ms); exudyn {exudyn.__version__}")
    print(f"two references (rtol 1e-11, 1e-10) differ by {whole:.1e} over the revolution (chaotic journal) and agree "
          f"to 1e-4 of the RMS slider velocity for {t_ref[-1] * 1e3:.2f} ms, the predictability horizon")
    print(f"error: relative RMS of the slider velocity against the rtol 1e-11 reference over the horizon "
          f"(floor: the references differ by {floor:.1e} there)\n")
    print(f"{'code':<10} {'setting':>14} {'CPU s':>8} {'error':>10}")
    ours, theirs = [], []
    for rtol in (1e-4, 1e-5, 1e-6, 1e-7, 1e-8):
        cpu, t, v = _wearbench(scene, t_end, rtol, args.repeat)
        err = _error(t, v, t_ref, v_ref)
        ours.append((cpu, err))
        print(f"{'wearbench':<10} {f'rtol {rtol:g}':>14} {cpu:8.3f} {err:10.2e}")
    for step in (2e-5, 1e-5, 5e-6, 2e-6, 1e-6, 5e-7):
        try:
            cpu, t, v = _exudyn(scene, bench, t_end, step, args.repeat)
        except (RuntimeError, ValueError) as exc:  # a diverging Newton at a coarse step is a result too
            print(f"{'exudyn':<10} {f'h {step:g} s':>14} {'failed':>8} {type(exc).__name__}: {str(exc)[:60]}")
            continue
        err = _error(t, v, t_ref, v_ref)
        theirs.append((cpu, err))
        print(f"{'exudyn':<10} {f'h {step:g} s':>14} {cpu:8.3f} {err:10.2e}")
    print("\nat equal error (CPU time of the cheapest run at least as accurate):")
    print(f"{'error':>10} {'wearbench s':>12} {'exudyn s':>10} {'exudyn / wearbench':>19}")
    for target in (1e-1, 3e-2, 1e-2, 3e-3, 1e-3):
        a, b = _time_at(target, ours), _time_at(target, theirs)
        ratio = b / a if math.isfinite(a) and math.isfinite(b) else math.nan
        print(f"{target:10.0e} {a:12.4f} {b:10.4f} {ratio:19.1f}")


if __name__ == "__main__":
    main()
