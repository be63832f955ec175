"""Is this version's trajectory bit for bit an earlier version's? The check for cost work that must not move it.

Runs the same cases with an earlier version (``--baseline DIR``: a scratch copy whose ``wearbench``
package lies in ``DIR/wearbench``, e.g. ``git archive main``) and with this one, each in its own
process, and compares everything a run returns with exact equality (NaN equal to NaN): every table
column (state, slider acceleration, contact columns, joint reactions), the step statistics (accepted
and rejected steps, right-hand sides, peak searches, drift), the dense-output peaks, the final state
and, where recorded, the contact records. Cases (test bed ``ninebar-testbed``):

- the nominal bench on new and on 400,000-cycle worn surfaces (0.3 mm), default method;
- drawn realisations (seeds; tolerances, random journal start, motor speed ripple: the speed-profile
  path) on both surfaces, with contact records;
- the paper's RK4 with Baumgarte stabilisation and table samples from full right-hand sides
  (``evaluate_samples``), the tight method, and kinematics of the fully driven ideal bench;
- wear: one short wear stage (``run_stages``: two surface updates from unworn surfaces, its surfaces,
  volumes and counts) and the wear of a worn run's contact record under each footprint
  (``accumulate_wear``: pressure, hertz, region).

Prints one row per case and exits with status 1 if any output differs. The motion is chaotic, so one
changed rounding anywhere shows within a revolution.

The earlier version's outputs can be recorded once (``--record FILE``, with ``--baseline``): a SHA-256
of every array, kept per environment, i.e. what besides the source decides the bits (interpreter,
numerical libraries, the CPU numba compiles for). ``--recorded FILE`` then runs this version only and
compares it with the record made in this environment (the same bits give the same digests), and exits
with status 3 when there is none, so the caller can run the baseline instead.

Run:  git archive main | tar -x -C /tmp/wb_main/wearbench   (mkdir -p it first)
      .venv/bin/python -m benchmarks.model.trajectory_identity --baseline /tmp/wb_main [--revolutions 3] [--seeds 2]
      ... --baseline /tmp/wb_main --record FILE     (the baseline's digests, added to FILE)
      ... --recorded FILE                           (this version against FILE's record)
      ... --has-record FILE                         (is there one for this environment?)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

STATES = {"new": "0.3 mm new", "worn": "0.3 mm second wear"}
RECORD_SCHEMA = "wearbench-trajectory-record/1"
NOT_RECORDED = 3  # exit status of --recorded when FILE holds no record made in this environment


def _cases(revolutions: float, seeds: int) -> list[dict]:
    cases = [{"name": f"nominal {s}", "state": s, "seed": None, "revolutions": revolutions} for s in STATES]
    for s in STATES:
        cases += [{"name": f"seed {seed} {s}", "state": s, "seed": seed, "revolutions": 1.0, "settle": 1.0,
                   "record_contacts": True} for seed in range(seeds)]
    cases += [
        {"name": "rk4-paper evaluated new", "state": "new", "seed": None, "revolutions": 0.05, "method": "rk4-paper",
         "step": 1e-5, "evaluate_samples": True},
        {"name": "default evaluated worn", "state": "worn", "seed": None, "revolutions": 0.2, "evaluate_samples": True},
        {"name": "accurate worn", "state": "worn", "seed": None, "revolutions": 0.2, "method": "accurate"},
        {"name": "kinematics ideal", "state": None, "seed": None, "revolutions": 1.0},
        {"name": "wear stage new", "state": "new", "wear": "stages"},
        {"name": "wear footprints worn", "state": "worn", "wear": "footprints", "revolutions": 0.2},
    ]
    return cases


def _wear(case: dict, bench, state) -> dict[str, np.ndarray]:
    """Every output of a wear case as named arrays: one short stage from unworn surfaces, or the wear of a
    worn run's contacts under each footprint."""
    from wearbench.model import simulate
    from wearbench.model.realisation import state_scene
    from wearbench.model.wear import WearLaw, accumulate_wear
    from wearbench.model.wear_stages import StagePlan, run_stages

    out = {}
    clearances = dict(state.clearances)
    if case["wear"] == "stages":
        plan = StagePlan(stages=1, stage_cycles=2000.0, min_updates=2)
        run = run_stages(bench, plan, clearances=clearances)
        stage = run.stages[0]
        for j, s in stage.surfaces.items():
            out[f"surfaces/{j}/bearing"], out[f"surfaces/{j}/journal"] = s.bearing, s.journal
            out[f"volume/{j}"] = np.array([stage.volume[j], stage.archard_volume[j]])
        out["counts"] = np.array([stage.counted_time, stage.updates, stage.revolutions], dtype=float)
        return out
    scene = state_scene(bench, state)
    res = simulate(scene, revolutions=case["revolutions"], record_contacts=True)
    geometry = bench.with_clearances(clearances)
    for j, record in res.contacts.items():
        for footprint in ("pressure", "hertz", "region"):
            law = WearLaw.from_bench(geometry, j, footprint=footprint)
            worn = accumulate_wear(record, law, scene.surfaces[j].bearing.size, surfaces=scene.surfaces[j])
            out[f"{footprint}/{j}/bearing"], out[f"{footprint}/{j}/journal"] = worn.bearing, worn.journal
    return out


def _run(case: dict) -> dict[str, np.ndarray]:
    """Every output of one case as named arrays."""
    from wearbench.bench.load import load_bench, shipped_bench
    from wearbench.model import simulate
    from wearbench.model.realisation import simulate_state, state_scene

    bench = load_bench(shipped_bench("ninebar-testbed"))
    if "wear" in case:
        return _wear(case, bench, {s.name: s for s in bench.states}[STATES[case["state"]]])
    options = {k: case[k] for k in ("method", "step", "evaluate_samples", "record_contacts") if k in case}
    if case["state"] is None:  # the fully driven ideal bench: kinematics + inverse dynamics
        bench = bench.with_clearances({j.name: None for j in bench.clearance_joints})
        res = simulate(state_scene(bench), revolutions=case["revolutions"], **options)
    else:
        state = {s.name: s for s in bench.states}[STATES[case["state"]]]
        if case["seed"] is None:
            res = simulate(state_scene(bench, state), revolutions=case["revolutions"], **options)
        else:
            from wearbench.model import realisation as R

            kept = {}
            inner = R.simulate

            def capture(*args, **kw):
                kept["res"] = inner(*args, **kw, **options)
                return kept["res"]

            R.simulate = capture
            try:
                simulate_state(bench, state, case["seed"], revolutions=case["revolutions"], settle=case["settle"])
            finally:
                R.simulate = inner
            res = kept["res"]
    out = {f"table/{c}": res.table[c].to_numpy() for c in res.table.columns}
    s = res.summary
    for key in ("steps", "rejected_steps", "function_evaluations", "peak_searches", "peak_slider_acc",
                "max_constraint_drift", "max_velocity_drift"):
        if key in s:
            out[f"summary/{key}"] = np.array([s[key]], dtype=float)
    for j, v in s["peak_fn"].items():
        out[f"summary/peak_fn/{j}"] = np.array([v])
    if res.final is not None:
        out["final/q"], out["final/v"] = res.final
    for j, frame in (res.contacts or {}).items():
        out[f"contacts/{j}"] = frame.to_numpy()
    return out


def environment() -> dict[str, str]:
    """What decides a compiled run's bits besides the source: the interpreter, the numerical
    libraries and the CPU numba compiles for (its name and a digest of its feature list)."""
    import llvmlite
    import llvmlite.binding as llvm
    import numba
    import pandas
    import scipy

    cpu = numba.config.CPU_NAME or llvm.get_host_cpu_name()
    features = numba.config.CPU_FEATURES or llvm.get_host_cpu_features().flatten()
    return {"python": platform.python_version(), "machine": platform.machine(), "numpy": np.__version__,
            "scipy": scipy.__version__, "pandas": pandas.__version__, "numba": numba.__version__,
            "llvmlite": llvmlite.__version__, "cpu": cpu,
            "cpu_features": hashlib.sha256(features.encode()).hexdigest()[:16]}


def _digest(a: np.ndarray) -> str:
    """SHA-256 of an array's dtype, shape and bytes: equal exactly where ``_same`` finds the arrays equal."""
    a = np.ascontiguousarray(a)
    return hashlib.sha256(f"{a.dtype.str}{a.shape}".encode() + a.tobytes()).hexdigest()


def digests(path: str) -> dict[str, str]:
    """Every array of a dump, by its key, as its digest."""
    with np.load(path) as arrays:
        return {k: _digest(arrays[k]) for k in arrays.files}


def _dump(path: str, revolutions: float, seeds: int) -> None:
    import wearbench.model

    arrays, clock = {}, {}
    _run({"name": "warm-up", "state": "new", "seed": None, "revolutions": 0.01})  # compiled before timing
    for case in _cases(revolutions, seeds):
        t0 = time.process_time()
        for key, value in _run(case).items():
            arrays[f"{case['name']}|{key}"] = value
        clock[case["name"]] = time.process_time() - t0
    np.savez(path, **arrays)
    print(json.dumps({"source": os.path.dirname(wearbench.model.__file__), "cpu": clock,
                      "environment": environment()}))


def _in_process(pythonpath: str | None, path: str, revolutions: float, seeds: int) -> dict:
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    cmd = [sys.executable, os.path.abspath(__file__), "--dump", path, "--revolutions", str(revolutions),
           "--seeds", str(seeds)]
    done = subprocess.run(cmd, check=False, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{cmd} failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind == "f":
        return bool(np.array_equal(a.view(np.uint64 if a.itemsize == 8 else np.uint32),
                                   b.view(np.uint64 if b.itemsize == 8 else np.uint32)))
    return bool(np.array_equal(a, b))


def _by_case(base: set[str], this: set[str], difference) -> list[tuple[str, int, int, str]]:
    """Per case: (name, arrays compared, arrays differing, first difference); ``difference(key)`` says
    how the key's two arrays differ ("" if not at all)."""
    rows = []
    for name in sorted({k.split("|")[0] for k in base | this}):
        keys = sorted(k for k in base | this if k.startswith(name + "|"))
        bad = []
        for k in keys:
            if k not in base or k not in this:
                bad.append(f"{k.split('|')[1]} only in {'this' if k in this else 'baseline'}")
            elif where := difference(k):
                bad.append(f"{k.split('|')[1]}{where}")
        rows.append((name, len(keys), len(bad), bad[0] if bad else ""))
    return rows


def compare(base: str, this: str) -> list[tuple[str, int, int, str]]:
    """Per case: (name, arrays compared, arrays differing, first difference) between two dumps."""
    A, B = np.load(base), np.load(this)

    def difference(k: str) -> str:
        a, b = A[k], B[k]
        if _same(a, b):
            return ""
        if a.shape != b.shape:
            return f" shapes {a.shape} vs {b.shape}"
        i = int(np.argmax(~((a == b) | (np.isnan(a) & np.isnan(b))).ravel()))
        return f" first at flat index {i}: {a.ravel()[i]!r} vs {b.ravel()[i]!r}"

    return _by_case(set(A.files), set(B.files), difference)


def compare_record(record: dict[str, str], this: dict[str, str]) -> list[tuple[str, int, int, str]]:
    """Per case, as ``compare``, between a record's digests and this version's."""
    return _by_case(set(record), set(this), lambda k: "" if record[k] == this[k] else " (digest differs)")


def _settings(args) -> dict:
    return {"revolutions": args.revolutions, "seeds": args.seeds}


def _held(file: str) -> dict:
    """A record file's content; exits naming the file if it is missing or not a record."""
    if not Path(file).exists():
        raise SystemExit(f"{file}: no such record file")
    held = json.loads(Path(file).read_text())
    if held.get("schema") != RECORD_SCHEMA:
        raise SystemExit(f"{file}: not a record of trajectory_identity.py's outputs (schema {held.get('schema')!r}, "
                         f"expected {RECORD_SCHEMA})")
    return held


def record_baseline(file: str, baseline: str, args) -> None:
    """Add (or replace) the record of the baseline's digests made in this environment to ``file``
    (rewritten through the output-file policy: a failed write leaves it as it was)."""
    from wearbench.bench.output_file import output_file
    from wearbench.model.digest import package_source_digest

    model = package_source_digest(Path(baseline) / "wearbench" / "model")
    held = _held(file) if Path(file).exists() else {"schema": RECORD_SCHEMA, "model": model, "records": []}
    if held["model"] != model:
        raise SystemExit(f"{file}: holds records of model {held['model'][:12]}; the baseline's model is "
                         f"{model[:12]}: use another file")
    with tempfile.TemporaryDirectory() as tmp:
        info = _in_process(baseline, os.path.join(tmp, "base.npz"), args.revolutions, args.seeds)
        arrays = digests(os.path.join(tmp, "base.npz"))
    key = {"environment": info["environment"], **_settings(args)}
    held["records"] = [r for r in held["records"] if {k: r[k] for k in key} != key] + [{**key, "arrays": arrays}]
    with output_file(file, force=True, option="--record") as tmp:
        tmp.write_text(json.dumps(held, indent=1, sort_keys=True) + "\n")
    print(f"{file}: model {model[:12]}, {len(arrays)} arrays recorded for {info['environment']}")


def _record_here(file: str, args) -> dict | None:
    """``file``'s record made in this environment with these settings, if any."""
    key = {"environment": environment(), **_settings(args)}
    return next((r for r in _held(file)["records"] if {k: r[k] for k in key} == key), None)


def _recorded(record: dict, args) -> tuple[dict, list[tuple[str, int, int, str]]]:
    """This version against a record: (this run's info, rows)."""
    with tempfile.TemporaryDirectory() as tmp:
        info = _in_process(None, os.path.join(tmp, "this.npz"), args.revolutions, args.seeds)
        rows = compare_record(record["arrays"], digests(os.path.join(tmp, "this.npz")))
    return info, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="directory holding the earlier version's wearbench package")
    ap.add_argument("--record", metavar="FILE", help="with --baseline: run the baseline only and add the digests "
                    "of its outputs, for this environment, to FILE")
    ap.add_argument("--recorded", metavar="FILE", help="run this version only, against FILE's record made in this "
                    f"environment (exit status {NOT_RECORDED} if there is none)")
    ap.add_argument("--has-record", metavar="FILE", help="run nothing: exit status 0 if FILE holds a record made in "
                    f"this environment, else {NOT_RECORDED}")
    ap.add_argument("--revolutions", type=float, default=3.0, help="revolutions of the nominal cases")
    ap.add_argument("--seeds", type=int, default=2, help="drawn realisations per surface state (1 revolution "
                    "after 1 settling)")
    ap.add_argument("--dump", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.dump:
        _dump(args.dump, args.revolutions, args.seeds)
        return
    if args.recorded or args.has_record:
        file = args.recorded or args.has_record
        record = _record_here(file, args)
        if record is None:
            print(f"{file}: no record made in this environment ({environment()}) with {_settings(args)}")
            sys.exit(NOT_RECORDED)
        if args.has_record:
            return
        info_t, rows = _recorded(record, args)
        info_b = {"source": f"{file} (recorded)", "cpu": {}}
    elif not args.baseline:
        ap.error("--baseline DIR or --recorded FILE is needed (see the docstring)")
    elif args.record:
        record_baseline(args.record, args.baseline, args)
        return
    else:
        with tempfile.TemporaryDirectory() as tmp:
            base, this = os.path.join(tmp, "base.npz"), os.path.join(tmp, "this.npz")
            info_b = _in_process(args.baseline, base, args.revolutions, args.seeds)
            info_t = _in_process(None, this, args.revolutions, args.seeds)
            rows = compare(base, this)
    print(f"baseline {info_b['source']}\nthis     {info_t['source']}")
    print(f"{'case':<28} {'arrays':>6} {'differ':>6} {'base s':>7} {'this s':>7}  first difference")
    for name, count, bad, first in rows:
        print(f"{name:<28} {count:6d} {bad:6d} {info_b['cpu'].get(name, 0):7.2f} {info_t['cpu'].get(name, 0):7.2f}"
              f"  {first}")
    differ = sum(r[2] for r in rows)
    print("IDENTICAL: every output bit for bit" if differ == 0 else f"DIFFERENT: {differ} arrays differ")
    sys.exit(1 if differ else 0)


if __name__ == "__main__":
    main()
