"""The [emulator] table's truth and sensor chain: validation errors name file, key, value and what
was expected; the programmatic builder for (bench, state, seed, sensor chain)."""

from __future__ import annotations

import pytest
from wearbench.bench.schema import BenchError
from wearbench.hardware.emulators.config import EmulatorConfig, emulator_config

pytestmark = pytest.mark.no_kernels


@pytest.mark.parametrize("table, key, expected", [
    ({"truth": {"seed": 3, "twin": True}}, "emulator.truth.twin", "twin = false or no twin key"),
    ({"truth": {"twin": False}}, "emulator.truth.twin", "expected a seed"),
    ({"truth": {"seed": -1}}, "emulator.truth.seed", "[0, 2147483647]"),
    ({"truth": {"seed": 1.5}}, "emulator.truth.seed", "integer"),
    ({"truth": {"state": "0.4 mm new"}}, "emulator.truth.state", "[[state]] names"),
    ({"truth": {"state": "0.6 mm new", "clearances": {"A": "0.5 mm"}}}, "emulator.truth.clearances",
     "no clearances with state"),
    ({"truth": {"seed": 1}, "motor": {"ripple": 0.01}}, "emulator.motor.ripple", "[tolerances] speed and ripple"),
    ({"accelerometer": {"aa_filter": "chebyshev"}}, "emulator.accelerometer.aa_filter", "butterworth"),
    ({"accelerometer": {"aa_cutoff": 0.6}}, "emulator.accelerometer.aa_cutoff", "0.5"),
    ({"accelerometer": {"aa_order": 0}}, "emulator.accelerometer.aa_order", "[1, 12]"),
    ({"accelerometer": {"spread": {"mode": ["3 kHz", "300 Hz"]}}}, "emulator.accelerometer.spread.mode",
     "low <= high"),
    ({"accelerometer": {"spread": {"mode": "1 kHz"}}}, "emulator.accelerometer.spread.mode", "[low, high]"),
    ({"accelerometer": {"spread": {"sensitivity": 0.7}}}, "emulator.accelerometer.spread.sensitivity", "0.5"),
    ({"accelerometer": {"spread": {"cross": 0.1}}}, "emulator.accelerometer.spread.cross", "unknown key"),
    ({"accelerometer": {"sensitivity": 3}}, "emulator.accelerometer.sensitivity", "2.0"),
    ({"revolutions": 2.5}, "emulator.revolutions", "integer"),
    ({"settle": -1}, "emulator.settle", "[0.0, 50.0]"),
])
def test_truth_and_chain_errors_name_file_key_value(testbed, table, key, expected):
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table(table, bench=testbed)
    assert e.value.key == key and "ninebar-testbed.toml" in str(e.value)
    assert expected in str(e.value), str(e.value)


def test_a_truth_without_seed_is_the_twin(testbed):
    assert EmulatorConfig.from_table({}, bench=testbed).truth.twin
    assert EmulatorConfig.from_table({"truth": {"twin": True}}, bench=testbed).truth.seed is None
    seeded = EmulatorConfig.from_table({"truth": {"seed": 0, "twin": False}}, bench=testbed)
    assert seeded.truth.seed == 0 and not seeded.truth.twin


def test_the_shipped_test_bed_plays_a_drawn_truth_through_a_realistic_chain(testbed):
    cfg = EmulatorConfig.from_bench(testbed)
    assert cfg.truth.seed is not None and cfg.revolutions >= 30
    assert cfg.truth.wear_stage in {s.name for s in testbed.states}
    a = cfg.accelerometer
    assert a.aa_filter == "butterworth" and a.aa_cutoff * testbed.sensor("accelerometer").sample_rate <= 0.4e4
    assert a.resonance > testbed.sensor("accelerometer").sample_rate and a.noise > 0
    assert testbed.sensor("accelerometer").range >= 400 * 9.80665  # impacts reach ~200 g (see the bench file)


def test_config_builder_names_a_state_and_round_trips(testbed):
    cfg = emulator_config(testbed, "0.3 mm first wear", 7, accelerometer={"noise": "0.2 m/s^2"}, revolutions=25)
    state = next(s for s in testbed.states if s.name == "0.3 mm first wear")
    assert cfg.truth.seed == 7 and not cfg.truth.twin and cfg.truth.wear_stage == state.name
    assert dict(cfg.truth.clearances) == dict(state.clearances) and dict(cfg.truth.wear) == dict(state.surfaces)
    assert cfg.motor.ripple == 0 and cfg.revolutions == 25  # the draw has its own ripple
    assert cfg.accelerometer.noise == pytest.approx(0.2)
    assert cfg.seed == 7 and emulator_config(testbed, "0.3 mm first wear", 7, noise_seed=3).seed == 3
    assert cfg.accelerometer.aa_filter == EmulatorConfig.from_bench(testbed).accelerometer.aa_filter  # kept
    assert EmulatorConfig.from_table(cfg.to_table(), bench=testbed) == cfg
    twin = emulator_config(testbed, state, None, table={"motor": {"ripple": 0.002}, "truth": {"accel_delay": "1 ms"}})
    assert twin.truth.twin and dict(twin.truth.wear) == dict(state.surfaces) and twin.motor.ripple == 0.002
    assert twin.truth.accel_delay == pytest.approx(1e-3)
    assert EmulatorConfig.from_table(twin.to_table(), bench=testbed) == twin
    nominal = emulator_config(testbed, None, 2)
    assert nominal.truth.clearances == {} and nominal.truth.seed == 2


@pytest.mark.parametrize("argv, seed, stage", [
    ([], 1, "0.3 mm new"),                                    # the bench file's truth
    (["--twin"], None, "0.3 mm new"),
    (["--seed", "5", "--state", "0.3 mm second wear"], 5, "0.3 mm second wear"),
    (["--state", "0.6 mm new"], 1, "0.6 mm new"),
])
def test_emulate_command_sets_the_truth(monkeypatch, argv, seed, stage):
    import wearbench.hardware.emulators.serial_server as server
    from wearbench.bench.load import shipped_bench
    from wearbench.cli import main

    served = []
    monkeypatch.setattr(server, "serve", lambda bench, config, **kw: served.append(config) or 0)
    assert main(["emulate", str(shipped_bench("ninebar-testbed")), "--serial", *argv]) == 0
    truth = served[0].truth
    assert truth.seed == seed and truth.wear_stage == stage
    assert bool(truth.wear) == ("wear" in stage)


def test_a_sensor_spread_draws_one_path_per_truth_seed(testbed):
    """[emulator.accelerometer.spread]: each drawn truth gets its own mount mode, damping and
    sensitivity within the ranges, the same for every session of that seed, and the config
    round-trips; a twin keeps the bench file's path."""
    spread = {"spread": {"mode": ["300 Hz", "3 kHz"], "damping": [0.02, 0.1], "sensitivity": 0.05}}
    paths = [emulator_config(testbed, "0.3 mm new", seed, accelerometer=spread).accelerometer for seed in range(40)]
    modes = [a.resonance for a in paths]
    assert all(300 <= m <= 3000 for m in modes) and len(set(modes)) == 40
    # an empty table draws these ranges, the defaults the file's comment states
    assert emulator_config(testbed, "0.3 mm new", 3, accelerometer={"spread": {}}).accelerometer == paths[3]
    assert all(0.02 <= a.damping <= 0.1 and 0.95 <= a.sensitivity <= 1.05 for a in paths)
    # log-uniform: about half the modes below the geometric middle (949 Hz)
    assert 10 <= sum(m < 949 for m in modes) <= 30
    again = emulator_config(testbed, "0.6 mm new", 7, accelerometer=spread)
    assert again.accelerometer == paths[7]  # the bench's path, whatever its state
    assert EmulatorConfig.from_table(again.to_table(), bench=testbed) == again
    twin = emulator_config(testbed, "0.3 mm new", None, accelerometer=spread).accelerometer
    assert twin.resonance == 25e3 and twin.sensitivity == 1.0


def test_a_config_that_is_not_a_table_is_one_clear_error(testbed):
    """A JSON file of the [emulator] table holding a list (wearbench emulate --config, --option config=)."""
    with pytest.raises(BenchError) as e:
        EmulatorConfig.from_table([1, 2], bench=testbed, source="cfg.json")
    assert str(e.value) == "cfg.json: emulator = [1, 2]: expected a table"


def test_the_serial_emulators_name_carries_the_marks_of_its_truth_not_the_truth(testbed):
    """Issue 44: what lets a host refuse labels the emulator does not play (hardware/protocol/truth.py)."""
    from wearbench.hardware.emulators.device import BenchDevice, ManualClock
    from wearbench.hardware.emulators.serial_server import SerialEmulator
    from wearbench.hardware.protocol.truth import read_marks

    names = {}
    for state in ("0.3 mm new", "0.6 mm new", "0.3 mm first wear"):
        cfg = emulator_config(testbed, state, None, signal="none")
        names[state] = SerialEmulator(BenchDevice(testbed, cfg, ManualClock())).name
        assert read_marks(names[state]) == cfg.truth.marks(testbed)
        assert names[state].startswith("wearbench emulator ninebar-testbed truth A=") and "mm" not in names[state]
    new, wide, worn = (read_marks(names[s]) for s in names)
    assert all(new[j][0] != wide[j][0] and new[j][1] == wide[j][1] for j in "AB")  # clearance differs, wear not
    assert all(new[j][0] == worn[j][0] and new[j][1] != worn[j][1] for j in "AB")  # wear differs, clearance not
