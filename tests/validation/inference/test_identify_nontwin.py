"""Identification on sessions whose truth is not a candidate theory.

Each session's emulator plays a bench drawn from the test bed's [tolerances] with a seed no
ensemble uses (other masses, lengths, friction, speed, start state) through the test bed's sensor
chain, recorded through the sim backend to MCAP, against the test bed's shipped ensembles (64
realisations per state, whose freshness test_ensemble.py checks). Two draws per state and 10-cycle
sessions keep this to about a minute; ``benchmarks/validation/identify.py`` runs the full-size version.
"""

from __future__ import annotations

import pytest
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.compute import Task, compute_client, run_tasks, task_key
from wearbench.compute.options import QUIET
from wearbench.synthetic.truths import prepare_truth, record_state, slug
from wearbench.validation.inference.ensemble import EnsembleSettings, build_ensembles
from wearbench.validation.inference.identify import NONE, UNDECIDED
from wearbench.validation.workflows.assess import assess_sessions

pytestmark = pytest.mark.slow

SETTINGS = EnsembleSettings()
CYCLES = 10


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    bench = load_bench(shipped_bench("ninebar-testbed"))
    states = bench.states
    truths = [(s, 7000 + 10 * k + d) for k, s in enumerate(states) for d in range(2)]
    out = tmp_path_factory.mktemp("nontwin")
    ensembles = build_ensembles(bench, states, settings=SETTINGS, compute=QUIET)  # shipped: no simulation
    with compute_client(workers=2):
        run_tasks([Task(prepare_truth, {"bench": bench, "state": s, "seed": seed, "revolutions": 14},
                        task_key("test-truth", s.name, seed), s.name) for s, seed in truths], cache=False)
    paths = []
    for s, seed in truths:
        paths.append(out / f"{slug(s.name)}_{seed}.mcap")
        record_state(bench, s, seed, paths[-1], backend="sim", cycles=CYCLES, revolutions=14)
    return bench, ensembles, truths, paths


def test_non_twin_sessions_get_their_clearance_and_wear_class_first(case):
    """Every session's top state has its clearance, and all but at most one of the eight has new or
    worn as its truth; which of the two wear stages is on top is not asserted here: they are 2-12 um
    of wear apart, about four standard deviations at 20 cycles and two at these 10, so on eight
    sessions it is a coin the benchmark counts (``benchmarks/validation/identify.py``: top-1 0.96 at 10 cycles
    over 80 sessions), not a unit test's to call. New against first wear at 0.3 mm is nearly as
    close at 10 cycles: the same seeds simulated on another machine (the motion is chaotic, so the
    realisations differ from the first rounding difference on) put one 0.3 mm new session on first
    wear (p 0.54 against 0.42 for new), where the development machine put all eight on their class.
    So one session of eight may take the neighbouring class; two, a wrong clearance or a wrong state
    named fail."""
    _, ensembles, truths, paths = case
    assessed = assess_sessions(paths, ensembles=ensembles)
    worn = {s.name for s, _ in truths if s.surfaces}
    clearance = {s.name: s.clearances for s, _ in truths}
    wrong_class = []
    for a, (s, _) in zip(assessed, truths, strict=True):
        post = a.identification.posterior
        top = max(post, key=post.get)
        assert clearance[top] == s.clearances, (s.name, post)
        if (top in worn) != (s.name in worn):
            wrong_class.append((s.name, post))
    assert len(wrong_class) <= 1, wrong_class
    verdicts = [(s.name, a.identification.verdict) for a, (s, _) in zip(assessed, truths, strict=True)]
    for a, (s, _) in zip(assessed, truths, strict=True):
        r = a.identification
        assert r.cycles >= CYCLES - 2 and abs(sum(r.posterior.values()) - 1) < 1e-9
        assert r.verdict in (s.name, UNDECIDED, NONE), (s.name, r.verdict, r.posterior)  # never a wrong state
    # "none of the candidates" for the true state: the consistency test's false alarms (0.03 of
    # 20-cycle sessions in benchmarks/validation/identify.py; these are 10 cycles): at most one of eight
    assert sum(v == NONE for _, v in verdicts) <= 1, verdicts


def test_a_state_that_is_not_a_candidate_is_not_named_with_high_probability(case):
    _, ensembles, truths, paths = case
    missing = "0.6 mm new"
    others = {k: v for k, v in ensembles.items() if k != missing}
    mine = [p for p, (s, _) in zip(paths, truths, strict=True) if s.name == missing]
    for a in assess_sessions(mine, ensembles=others):
        assert a.identification.verdict in (NONE, UNDECIDED), a.identification
        assert not any(a.identification.consistent.values()), a.identification.p_value


def test_identify_command_with_saved_ensembles(case, tmp_path, capsys):
    import json

    from wearbench.cli import main
    from wearbench.validation.inference.ensemble import ensembles_key, save_ensembles
    bench, ensembles, _, paths = case
    saved = save_ensembles(ensembles, tmp_path / "e.npz", key=ensembles_key(bench, bench.states, bench.speed, SETTINGS),
                           bench=bench, states=bench.states)
    out = tmp_path / "ids.json"
    assert main(["identify", str(paths[0]), str(paths[2]), "--ensembles", str(saved), "--json", str(out),
                 "--out", str(tmp_path / "report")]) == 0
    rows = json.loads(out.read_text())
    assert [r["session"] for r in rows] == [paths[0].stem, paths[2].stem]
    assert all(abs(sum(r["posterior"].values()) - 1) < 1e-9 for r in rows)
    assert "posterior probability" in capsys.readouterr().out
    html = (tmp_path / "report" / "report.html").read_text()
    assert "Which state explains each session" in html and "band_" in html
    # a bad threshold is one clear line, exit 2
    assert main(["identify", str(paths[0]), "--ensembles", str(saved), "--threshold", "1.5"]) == 2


def test_plain_compare_gives_one_verdict_per_session(case, tmp_path, capsys):
    """`wearbench compare` without --theory on sessions whose bench names states: identified first,
    windows judged against the identified state only, or "cannot decide"; no second grade."""
    import json

    from wearbench.cli import main
    paths = case[3]
    out = tmp_path / "report"
    assert main(["compare", str(paths[0]), str(paths[2]), "--out", str(out)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines()
             if ln.startswith((paths[0].stem + ":", paths[2].stem + ":"))]
    assert len(lines) == 2
    scores = json.loads((out / "scores.json").read_text())
    assert scores["summary"] == [] and scores["sessions"] == []  # no grade against a claimed state
    for line, row in zip(lines, scores["identification"], strict=True):
        if row["verdict"] in row["posterior"]:
            assert f"windows against {row['verdict']}:" in line and row["window_state"] == row["verdict"]
        else:
            assert "cannot decide" in line and row["window_verdict"].startswith("cannot decide")
    assert "ISO R" not in (out / "report.html").read_text().split("Five-cycle windows")[0]
