"""Bench definition files: every shipped file loads; each kind of mistake gets its own clear error."""

from __future__ import annotations

import math

import pytest
from wearbench.bench.load import BENCH_DIR, load_bench, parse_bench, shipped_bench
from wearbench.bench.schema import BenchError

NINEBAR = shipped_bench("ninebar")
SHIPPED = sorted(BENCH_DIR.glob("*.toml"))


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_bench_loads(path):
    bench = load_bench(path)
    assert bench.bodies and bench.joints and bench.drivers
    assert bench.sha256 and bench.source.startswith("#")


def test_ninebar_values_are_the_reference_notes():
    b = load_bench(NINEBAR)
    assert b.speed == pytest.approx(-5 * math.pi)
    assert {j.name for j in b.clearance_joints} == {"A", "B"}
    a = b.joint("A").clearance
    assert a.bearing_radius == pytest.approx(0.015)
    assert a.radial_clearance == pytest.approx(0.6e-3)
    assert a.bearing_material.youngs_modulus == pytest.approx(206e9)
    assert a.contact.restitution == 0.9 and a.contact.friction_coefficient == 0.1
    assert [math.degrees(d.phase) for d in b.drivers] == pytest.approx([-36.84, 24.31])
    assert b.body("link8").mass == pytest.approx(1.060)
    assert b.body("rod2").points["end"] == pytest.approx((0.2, 0.0))
    assert b.ground_points["O4"] == pytest.approx((0.0, -0.35))


def test_slider_crank_is_flores_benchmark():
    b = load_bench(shipped_bench("slider-crank"))
    s = b.joint("S").clearance
    assert (s.bearing_radius, s.journal_radius) == pytest.approx((0.010, 0.0095))
    assert b.speed == pytest.approx(5000 * 2 * math.pi / 60)
    assert [b.body(n).mass for n in ("crank", "rod", "slider")] == pytest.approx([0.30, 0.21, 0.14])


def test_with_clearances_keeps_bearing_and_can_make_ideal():
    b = load_bench(NINEBAR).with_clearances({"A": 0.1e-3, "B": None})
    assert b.joint("A").clearance.journal_radius == pytest.approx(0.0149)
    assert b.joint("B").clearance is None
    with pytest.raises(KeyError, match="no clearance joint"):
        b.with_clearances({"C": 1e-4})


def _broken(old: str, new: str, count: int = 1) -> str:
    text = NINEBAR.read_text()
    assert old in text, old
    return text.replace(old, new, count)


SECOND_ACCELEROMETER = """[[sensor]]
name = "rod_acc"
kind = "accelerometer"
body = "rod2"
point = "end"
axis = "0 deg"
range = "50 g"
sample_rate = "10 kHz"

"""
SECOND_ENCODER = """[[sensor]]
name = "rocker_encoder"
kind = "encoder"
joint = "O4"
counts_per_rev = 1000
sample_rate = "1 kHz"

"""

# (replacement old, new) -> (key fragment, value fragment, expectation fragment)
MISTAKES = {
    "typo key": (('mass = "0.942 kg"', 'masss = "0.942 kg"'), "masss", "0.942 kg", "unknown key"),
    "negative length": (('length = "0.40 m"', 'length = "-0.40 m"'), "rod2", "-0.40 m", "positive length"),
    "journal larger": (('journal_radius = "14.4 mm"', 'journal_radius = "15.2 mm"'), "journal_radius",
                       "15.2 mm", "smaller than its bearing"),
    "bare number": (('length = "0.10 m"', "length = 0.10"), "length", "0.1", "no unit"),
    "wrong unit": (('mass = "0.5 kg"', 'mass = "0.5 m"'), "slider", "0.5 m", "not a mass unit"),
    "unknown body": (('bodies = ["link8", "slider"]', 'bodies = ["link9", "slider"]'), "joint[7] (E).bodies",
                     "link9", "expected 'frame' or a body"),
    "unknown point": (('points = ["O4", "start"]', 'points = ["O5", "start"]'), "joint[2] (O4).points",
                      "O5", "expected a point of frame"),
    "unknown material": (('journal_material = "steel"', 'journal_material = "bronze"'), "journal_material",
                         "bronze", "material defined under [materials]"),
    "restitution range": (("restitution = 0.9", "restitution = 1.5"), "contact.restitution", "1.5",
                          "number in (0.0, 1.0]"),
    "prismatic axis": (('axis = "90 deg"                # guide', '# no axis'), "guide", "None",
                       "missing required angle"),
    "driver not a pivot": (('joint = "O4"\nratio', 'joint = "E"\nratio'), "driver[1].joint", "E",
                           "revolute joint to the frame"),
    "syntax": (('[[body]]\nname = "rod2"', '[[body]\nname = "rod2"'), "(syntax)", "None", "not valid TOML"),
    "too fast": (('speed = "-5pi rad/s"', 'speed = "-5000 rpm"'), "operating.speed", "-5000 rpm",
                 "motor's max_speed"),
    "friction ramp": (('friction_vm = "1e-3 m/s"', 'friction_vm = "1e-5 m/s"'), "contact.friction_vm",
                      "1e-5 m/s", "friction_vm > friction_v0"),
    "missing mass": (('mass = "0.471 kg"\n', ""), "rocker6", "None", "missing required key"),
    "worn file missing": (('axial_length = "20 mm"         # FILLED IN',
                           'axial_length = "20 mm"\nsurfaces = "worn/nowhere.npz"'), "surfaces",
                          "worn/nowhere.npz", "does not exist"),
    "sensor body": (('body = "slider"\npoint', 'body = "carriage"\npoint'), "sensor[0].body", "carriage",
                    "expected one of"),
    "unknown backend": (('backend = "sim"', 'backend = "usb"'), "hardware.backend", "usb", "expected one of"),
    # issue 44: sensors wearbench would have ignored or silently replaced are refused
    "encoder on a joint not driven": (('joint = "O1"\ncounts_per_rev', 'joint = "H"\ncounts_per_rev'),
                                      "sensor[1] (crank_encoder).joint", "H", "expected a driven joint"),
    "second accelerometer": (("[hardware]", SECOND_ACCELEROMETER + "[hardware]"), "sensor[2] (rod_acc).kind",
                             "accelerometer", "expected one accelerometer per bench: sensor[0] (slider_acc)"),
    "second encoder": (("[hardware]", SECOND_ENCODER + "[hardware]"), "sensor[2] (rocker_encoder).kind",
                       "encoder", "expected one encoder per bench: sensor[1] (crank_encoder)"),
    "sensor name twice": (('name = "crank_encoder"', 'name = "slider_acc"'), "sensor[1] (slider_acc).name",
                          "slider_acc", "unique sensor name"),
}


@pytest.mark.parametrize("case", sorted(MISTAKES))
def test_broken_bench_gives_one_clear_error(case, tmp_path):
    (old, new), key, value, expected = MISTAKES[case]
    path = tmp_path / "broken.toml"
    path.write_text(_broken(old, new))
    _assert_one_clear_error(path, key, value, expected)


def _assert_one_clear_error(path, key: str, value: str, expected: str) -> None:
    with pytest.raises(BenchError) as info:
        load_bench(path)
    err = info.value
    message = str(err)
    assert str(path) in message
    assert key in err.key, (err.key, message)
    assert value in repr(err.value) or value == str(err.value), (err.value, message)
    assert expected in err.expected, message


def test_unreadable_file_names_it(tmp_path):
    with pytest.raises(BenchError, match="cannot read the bench file"):
        load_bench(tmp_path / "missing.toml")


def test_parse_text_without_file():
    bench = parse_bench(NINEBAR.read_text())
    assert bench.path is None and bench.name == "ninebar"


def test_mechanism_that_does_not_assemble(tmp_path):
    """Link 8 shorter than the distance from D to the guide: the loop cannot close."""
    from wearbench.model import build_scene

    path = tmp_path / "short-link8.toml"
    path.write_text(_broken('length = "0.45 m"', 'length = "0.10 m"'))
    bench = load_bench(path)  # every value is valid on its own
    with pytest.raises(BenchError) as info:
        build_scene(bench)
    assert str(path) in str(info.value) and "assembl" in str(info.value)


TESTBED = shipped_bench("ninebar-testbed")

# mistakes in the test bed's [sensor.chain]: (old, new) -> (key fragment, value fragment, expectation fragment)
CHAIN_MISTAKES = {
    "cutoff without unit": (('filter_cutoff = "3 kHz"', "filter_cutoff = 3000"), "sensor[0].chain.filter_cutoff",
                            "3000", "no unit"),
    "unknown filter": (('filter = "butterworth"', 'filter = "chebyshev"'), "sensor[0].chain.filter", "chebyshev",
                       "expected one of"),
    "order missing": (("filter_order = 8\n", ""), "sensor[0].chain.filter_order", "None", "missing required"),
    "both filter and its delay": (('filter_cutoff = "3 kHz"', 'filter_cutoff = "3 kHz"\nfilter_delay = "0.27 ms"'),
                                  "sensor[0].chain.filter_delay", "0.27 ms", "not both"),
    "latency in Hz": (('latency = "0 ms"', 'latency = "0 Hz"'), "sensor[0].chain.latency", "0 Hz",
                      "not a time unit"),
    "no uncertainty": (('uncertainty = "0.05 ms"', ""), "sensor[0].chain.uncertainty", "None",
                       "missing required"),
    "typo": (('clock_drift = "20 ppm"', 'clock_drif = "20 ppm"'), "sensor[0].chain.clock_drif", "20 ppm",
             "unknown key"),
    "drift too large": (('clock_drift = "20 ppm"', 'clock_drift = "2000 ppm"'), "sensor[0].chain.clock_drift",
                        "2000 ppm", "within +/-1000 ppm"),
}


@pytest.mark.parametrize("case", sorted(CHAIN_MISTAKES))
def test_broken_sensor_chain_statement_gives_one_clear_error(case, tmp_path):
    (old, new), key, value, expected = CHAIN_MISTAKES[case]
    text = TESTBED.read_text()
    assert old in text, old
    path = tmp_path / "broken.toml"
    path.write_text(text.replace(old, new, 1).replace('"worn/', f'"{TESTBED.parent}/worn/'))
    _assert_one_clear_error(path, key, value, expected)


def test_the_test_beds_chain_statement_is_read_in_si():
    chain = load_bench(TESTBED).sensor("accelerometer").chain
    assert (chain.filter, chain.filter_order, chain.filter_cutoff) == ("butterworth", 8, 3000.0)
    assert chain.clock_drift == pytest.approx(20e-6) and chain.uncertainty == pytest.approx(5e-5)
    assert load_bench(NINEBAR).sensor("accelerometer").chain is None  # no statement: none invented


def test_bench_show_gives_the_stated_chain_delay(capsys):
    from wearbench.cli import main

    assert main(["bench", "show", "ninebar-testbed"]) == 0
    out = capsys.readouterr().out
    # 1 / (2 pi 3 kHz sin(pi/16)) = 0.272 ms for the 8th-order Butterworth
    assert "its chain, as stated: stated 0.272 ms" in out and "20 ppm clock drift" in out
