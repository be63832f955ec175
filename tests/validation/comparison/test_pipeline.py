"""The comparison pipeline on synthetic sessions built in memory (no acquisition, no model):
cycles from the encoder, crank-angle alignment, residual delay, windows, ranking, report files."""

import json
import re

import numpy as np
import pandas as pd
import pytest
from wearbench.reports.comparison import write_report
from wearbench.validation import (
    CompareOptions,
    MeasuredSession,
    compare_session,
    parse_filter,
    parse_windows,
    rank_theories,
)
from wearbench.validation.comparison.theory import TheoryCurve
from wearbench.validation.measurement.cycles import choose_windows, cut_cycles

FS = 10_000.0
PHASE = -0.643  # crank angle at t = 0 (rad), as the bench's driver phase


def profile(phi, spike=1.0):
    """Slider acceleration versus crank angle: two harmonics and one sharp 'impact' per turn."""
    return (40 * np.cos(phi) + 15 * np.cos(2 * phi + 0.5)
            + spike * 25 * np.exp(-((np.mod(phi, 2 * np.pi) - 2.0) / 0.05) ** 2))


def theory_table(spike=1.0, revs=3.0):
    t = np.arange(int(revs * FS)) / FS
    theta = PHASE + 2 * np.pi * t
    return pd.DataFrame({"t": t, "theta_O1": theta, "slider_acc": profile(theta, spike)})


def session(delay=0.0023, noise=0.5, spike=1.0, seconds=17.0, ripple=0.003, label="synthetic"):
    """Measured: acceleration late by ``delay`` s behind the crank, noise, bias, speed ripple,
    a 1 kHz encoder (absolute angle) with an index pulse at crank angle 0."""
    t = np.arange(int(seconds * FS)) / FS
    w = 2 * np.pi * (1 + ripple * np.sin(2 * np.pi * 0.2 * t))
    theta = PHASE + np.cumsum(w) / FS
    rng = np.random.default_rng(0)
    acc = profile(np.interp(t - delay, t, theta), spike) + rng.normal(0, noise, t.size) + 1.5
    te, ang = t[::10], theta[::10]
    index = np.zeros(te.size, bool)
    index[1:] = np.diff(np.floor(ang / (2 * np.pi))) > 0
    enc = pd.DataFrame({"time": te, "angle": ang, "speed": np.gradient(ang, te), "index": index})
    return MeasuredSession(label, pd.DataFrame({"time": t, "acc": acc}), enc)


def test_cycles_start_at_the_index_angle():
    s = session()
    assert s.start_angle == pytest.approx(0.0, abs=2 * np.pi / 1000) or s.start_angle == pytest.approx(2 * np.pi, abs=0.01)
    assert len(s.cycles) == 16 and s.cycles["steady"].all()
    # the crank is at angle 0 (mod 2 pi) at every cycle start
    enc = s.encoder
    a = np.interp(s.cycles["t_start"], enc["time"], enc["angle"])
    assert np.allclose(np.angle(np.exp(1j * a)), 0.0, atol=2e-3)  # within a third of an encoder step
    assert s.cycles["speed"].mean() == pytest.approx(2 * np.pi, rel=1e-3)
    # crank-angle view: one row per grid point per cycle, the profile recovered (delay = 0 here)
    s0 = session(delay=0.0, noise=0.0)
    view = s0.angles
    assert len(view) == 16 * 720
    first = view[view["cycle"] == 3]
    assert np.allclose(first["value"], profile(first["angle"].to_numpy()) + 1.5, atol=1.0)


def test_run_up_cycles_are_not_steady():
    t = np.arange(0, 12, 0.001)
    speed = 2 * np.pi * np.minimum(1.0, 0.25 + 0.1875 * t)  # ramps to 1 Hz by t = 4 s (2.5 turns)
    enc = pd.DataFrame({"time": t, "angle": np.cumsum(speed) * 0.001, "index": False})
    cyc = cut_cycles(enc, start_angle=0.0)
    assert not cyc["steady"].iloc[0] and cyc["steady"].iloc[-5:].all()
    assert choose_windows(cyc, parse_windows("all"))[0] >= 1


def test_windows_all_and_random():
    cyc = pd.DataFrame({"cycle": range(23), "steady": [True] * 23})
    assert choose_windows(cyc, parse_windows("all")) == [0, 5, 10, 15]
    a = choose_windows(cyc, parse_windows("random:3:7"))
    assert a == choose_windows(cyc, parse_windows("random:3:7")) and len(set(a)) == 3
    assert all(0 <= s <= 18 for s in a)
    with pytest.raises(ValueError, match="random:COUNT"):
        parse_windows("some")


def test_delay_recovered_and_perfect_theory_scores_high():
    c = compare_session(session(noise=0.0), theory_table(), options=CompareOptions())
    assert len(c.windows) == 3  # 16 steady cycles: three consecutive five-cycle windows
    for w in c.windows:
        assert w.shift_s == pytest.approx(-0.0023, abs=0.1 / FS)  # theory early by the sensor delay
        assert w.shift_deg == pytest.approx(-0.0023 * 360, abs=0.02)
        assert w.scores.iso_rating > 0.99 and w.scores.correlation > 0.9999


def test_without_shift_the_phase_score_rates_the_delay():
    opts = CompareOptions(apply_shift=False, filter=parse_filter("cfc180"))
    c = compare_session(session(noise=0.0), theory_table(), options=opts)
    w = c.windows[0]
    assert w.shift_s == pytest.approx(-0.0023, abs=0.1 / FS)
    assert w.scores.iso_lag_s == pytest.approx(-0.0023, abs=1.01 / FS)  # integer-sample ISO search
    n = 5 * FS
    assert w.scores.iso_phase == pytest.approx(1 - 23 / (0.2 * n), abs=1.01 / (0.2 * n))


def test_matching_theory_ranks_first():
    s = session(spike=1.0, noise=1.0)
    ranking = rank_theories(s, {"no impact": theory_table(0.0), "impact": theory_table(1.0),
                                "double impact": theory_table(2.0)},
                            options=CompareOptions(windows=parse_windows("random:2:1")))
    assert ranking[0].label == "impact"
    assert ranking[0].rating > ranking[1].rating


def test_theory_too_short_or_wrong_way():
    with pytest.raises(ValueError, match="needs one"):
        TheoryCurve.from_table(theory_table(revs=0.5), "O1")
    curve = TheoryCurve.from_table(theory_table(revs=3.0), "O1", periodic=False)
    with pytest.raises(ValueError, match="simulate more revolutions"):
        curve.at(np.linspace(0, 5 * 2 * np.pi, 100), direction=1.0)
    with pytest.raises(ValueError, match="other way"):
        curve.at(np.linspace(0, 1, 10), direction=-1.0)
    with pytest.raises(ValueError, match="slider_acc"):
        TheoryCurve.from_table(theory_table().drop(columns="slider_acc"), "O1")


def test_report_files(tmp_path):
    a = compare_session(session(label="0.3 mm"), theory_table())
    b = compare_session(session(spike=2.0, label="0.6 mm"), theory_table(2.0))
    ranks = rank_theories(session(spike=2.0), {"single": theory_table(1.0), "double": theory_table(2.0)},
                          options=CompareOptions(windows=parse_windows("random:1")))
    rep = write_report([a, b], tmp_path / "report", rankings={"0.6 mm": ranks})
    names = {p.name for p in rep.figures}
    assert {"sessions_measured.png", "sessions_comparison.png", "overlay_0.3_mm.png", "spectrum_0.6_mm.png"} <= names
    assert "scores_table.png" not in names  # the scores are an HTML table (was an image with 7 px text)
    assert all(p.stat().st_size > 5000 for p in rep.figures)
    html = rep.html.read_text()
    assert html.count("data:image/png;base64,") == len(rep.figures) and "src=\"report" not in html
    scores = json.loads(rep.scores_json.read_text())
    s0 = scores["sessions"][0]
    assert s0["label"] == "0.3 mm" and len(s0["windows"]) == 3
    assert s0["summary"]["iso_rating"]["mean"] == pytest.approx(a.rating)
    assert np.isfinite(s0["windows"][0]["shift_s"]) and s0["peak_acc_measured"] > 0
    assert scores["rankings"]["0.6 mm"][0]["label"] == "double"
    assert "best theory" in html
    table = re.search(r"<table class='scores'>(.*?)</table>", html).group(1)
    rows = re.findall(r"<tr>(.*?)</tr>", table)
    assert len(rows) == 3 and rows[0].count("<th>") == 13
    for row, entry in zip(rows[1:], scores["sessions"]):
        cells = re.findall(r"<td>(.*?)</td>", row)
        assert cells[0] == entry["label"].replace("&", "&amp;")
        mean, sd = (float(x) for x in cells[1].split(" ± "))  # ISO R, as scores.json has it
        assert mean == pytest.approx(entry["summary"]["iso_rating"]["mean"], abs=5e-4)
        assert sd == pytest.approx(entry["summary"]["iso_rating"]["std"], abs=5e-4)


def test_windows_with_dropped_samples_are_skipped_not_scored():
    s = session(noise=0.0)
    acc = s.acceleration
    hole = (acc["time"] > 7.2) & (acc["time"] < 7.25)  # 50 ms lost inside the second window
    gappy = MeasuredSession("gappy", acc[~hole].reset_index(drop=True), s.encoder)
    assert gappy.gaps == 1
    c = compare_session(gappy, theory_table())
    assert [w.start_cycle for w in c.windows] == [0, 10]
    assert c.skipped == [(5, "dropped samples in the window")]
    assert c.to_dict()["skipped"] == [{"start_cycle": 5, "reason": "dropped samples in the window"}]


def test_compare_sessions_api(tmp_path):
    from wearbench.reports.comparison import compare_sessions

    opts = CompareOptions(windows=parse_windows("random:1:0"), filter=parse_filter("butter:150:2"))
    rep = compare_sessions([session(label="a"), session(spike=2.0, label="b")], tmp_path,
                           theories=theory_table(), options=opts)
    assert [c.label for c in rep.sessions] == ["a", "b"]
    assert rep.sessions[0].rating > rep.sessions[1].rating  # b has twice the impact of the theory
    assert rep.scores["options"]["filter"].startswith("Butterworth low-pass 150 Hz")
    with pytest.raises(ValueError, match="theories for 2 sessions"):
        compare_sessions([session(), session()], tmp_path, theories=[theory_table()] * 3)
