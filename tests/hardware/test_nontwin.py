"""The non-twin emulator: a truth drawn from the bench's tolerances, played as a long run with real
cycle-to-cycle variation, whose encoder and acceleration belong to one motion."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal as sps
from wearbench.hardware.emulators.config import emulator_config
from wearbench.hardware.emulators.device import (
    AccelBlock,
    BenchDevice,
    EncoderBlock,
    ManualClock,
    table_speed,
)
from wearbench.hardware.emulators.signal import FADE, run_table
from wearbench.model.realisation import draw_realisation, simulate_state

pytestmark = pytest.mark.slow  # model runs: about 15 s in all
STATE = "0.3 mm new"
REVS = 4  # revolutions played (the run simulates settle 2 + REVS + 2)
TWO_PI = 2 * math.pi


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    path = tmp_path_factory.mktemp("cache")
    mp.setenv("WEARBENCH_CACHE", str(path))
    yield path
    mp.undo()


@pytest.fixture(scope="module")
def tables(testbed, cache):
    """Run tables of seeds 1 and 2 at the test bed's speed."""
    out = {}
    for seed in (1, 2):
        cfg = emulator_config(testbed, STATE, seed, revolutions=REVS)
        out[seed] = run_table(testbed, cfg.truth, testbed.speed, revolutions=REVS)
    return out


def cycles(table) -> np.ndarray:
    """The table's revolutions as rows (one per cycle, the same crank angles in each column)."""
    return table.acc.reshape(round(table.revolutions), -1)


def test_seeds_differ_and_a_seed_reproduces_bit_for_bit(testbed, tables):
    a, b = cycles(tables[1]), cycles(tables[2])
    rms = np.sqrt(np.mean(a**2))
    assert np.sqrt(np.mean((a - b) ** 2)) > 0.2 * rms  # two draws: different impacts
    cfg = emulator_config(testbed, STATE, 1, revolutions=REVS, cache=False)
    again = run_table(testbed, cfg.truth, testbed.speed, revolutions=REVS, cache=False)  # simulated again
    np.testing.assert_array_equal(again.acc, tables[1].acc)


def test_a_rig_labelled_with_other_clearances_plays_the_same_run_under_the_same_key(testbed, tables):
    """The truth's clearances replace the bench's in the run, so a rig whose bench carries other
    clearance labels (``record --clearance``, the demo's sessions) finds the table prepared on the
    file's bench, and it is the run it would have simulated (before, the demo simulated two of its
    five truths twice); a joint the truth leaves out plays the rig's clearance, and keys another table."""
    from wearbench.hardware.emulators.signal import table_key

    truth = emulator_config(testbed, STATE, 1, revolutions=REVS).truth
    labelled = testbed.with_clearances({j.name: 0.6e-3 for j in testbed.clearance_joints})
    kw = {"kind": "seed1", "revolutions": REVS, "settle": 2.0, "rate": 2e4}
    assert table_key(labelled, truth, testbed.speed, **kw) == table_key(testbed, truth, testbed.speed, **kw)
    relabelled = run_table(labelled, truth, testbed.speed, revolutions=REVS, cache=False)
    np.testing.assert_array_equal(relabelled.acc, tables[1].acc)
    partial = dataclasses.replace(truth, clearances={"A": truth.clearances["A"]})
    assert table_key(labelled, partial, testbed.speed, **kw) != table_key(testbed, partial, testbed.speed, **kw)


def test_consecutive_cycles_differ_but_keep_their_low_passed_mean(tables):
    """Not a loop: every cycle differs from the next by more than 10 % of the signal's rms (chaotic
    impacts; measured 0.9-1.2 x rms over the 4 states x 4 seeds x 12 cycles), while each cycle's
    50 Hz low-passed curve in 10-degree crank-angle bins stays within 40 % of the range of the mean
    curve over the cycles (measured at most 33 %) and follows its shape (correlation > 0.9): the
    mechanism's motion, on which the impacts ride, crank angle for crank angle."""
    for table in tables.values():
        c = cycles(table)
        rms = np.sqrt(np.mean(c**2))
        diffs = np.sqrt(np.mean(np.diff(c, axis=0) ** 2, axis=1))
        assert np.all(diffs > 0.1 * rms), diffs / rms
        fs = c.shape[1] * abs(table.speed) / TWO_PI  # samples per second at the table's speed
        low = sps.sosfiltfilt(sps.butter(4, 50.0, fs=fs, output="sos"), table.acc).reshape(c.shape)
        edges = np.arange(36) * c.shape[1] // 36  # 10-degree crank-angle bins
        binned = np.add.reduceat(low, edges, axis=1) / np.diff(np.append(edges, c.shape[1]))
        mean = binned.mean(axis=0)
        assert np.abs(binned - mean).max() < 0.4 * np.ptp(mean), np.abs(binned - mean).max() / np.ptp(mean)
        assert all(np.corrcoef(row, mean)[0, 1] > 0.9 for row in binned)


@pytest.fixture(scope="module")
def run1(testbed):
    """The realisation of seed 1 simulated directly (not through the emulator's table)."""
    return simulate_state(testbed, testbed.states[0], 1, revolutions=REVS + 2.0, speed=testbed.speed,
                          output_rate=20000.0)


def test_a_long_session_wraps_without_a_jump(tables, run1):
    """Past its end the run plays again from its start; the last quarter revolution fades into the
    samples that preceded the start in the simulation, so the wrap is no larger a step than the
    run's own at that crank angle (and no crossfade lies in the first REVS - 1/4 revolutions)."""
    table = tables[1]
    assert table.period == REVS * TWO_PI
    start = TWO_PI * math.ceil((run1.motor_angle[0] + FADE) / TWO_PI)  # device angle 0 in the run
    step = table.period / table.acc.size
    natural = abs(np.interp(start, run1.motor_angle, run1.acc) - np.interp(start - step, run1.motor_angle, run1.acc))
    assert abs(table.acc[-1] - table.acc[0]) <= natural + 1e-6 * np.abs(table.acc).max()
    played = np.arange(0, table.period - FADE, step)
    np.testing.assert_allclose(table.at(played), np.interp(start + played, run1.motor_angle, run1.acc),
                               rtol=0, atol=1e-9 * np.abs(table.acc).max())
    np.testing.assert_allclose(table.at(played[:5000] + table.period), table.at(played[:5000]),
                               rtol=0, atol=1e-6 * np.abs(table.acc).max())


def stream(bench, config, seconds, rate=20000.0):
    clock = ManualClock()
    d = BenchDevice(bench, config, clock)
    d.configure_accelerometer(5000.0, rate)
    d.enable()
    d.set_speed(bench.speed)
    d.start_stream()
    blocks = []
    for _ in range(round(seconds / 0.05)):
        clock.advance(0.05)
        blocks += d.read()
    acc = [b for b in blocks if isinstance(b, AccelBlock)]
    enc = [b for b in blocks if isinstance(b, EncoderBlock)]
    return d, acc, enc


def test_encoder_and_acceleration_belong_to_the_realisation_motion(testbed):
    """The largest impact of a late revolution, as the device streams it, lands at the crank angle
    (from the encoder) where the realisation's own simulation has it; the encoder runs at the
    realisation's true speed (commanded x speed_scale), not the commanded one."""
    clean = {"noise": "0 m/s^2", "bias": "0 m/s^2", "adc_bits": 0, "drift": "0 ppm", "aa_filter": "none",
             "resonance": "0 Hz"}
    cfg = emulator_config(testbed, STATE, 1, revolutions=REVS, accelerometer=clean)
    real = draw_realisation(testbed, 1)
    assert real.speed_scale != 1.0 and real.ripple > 0
    d, acc, enc = stream(testbed, cfg, REVS - 0.3, rate=10000.0)
    x = np.concatenate([b.samples for b in acc]).astype(float)
    tx = np.concatenate([b.times for b in acc])
    counts = np.concatenate([b.counts for b in enc]).astype(float)
    te = np.concatenate([b.times for b in enc])
    cpr = d.counts_per_rev
    driver = testbed.drivers[0]
    # true speed from the encoder, over whole revolutions after the ramp
    done = te > 0.2
    span = np.flatnonzero(done)[[0, -1]]
    revs = np.floor((counts[span[1]] - counts[span[0]]) / cpr)
    i1 = span[0] + np.searchsorted(counts[span[0]:] - counts[span[0]], revs * cpr)
    speed = (counts[i1] - counts[span[0]]) * TWO_PI / cpr / (te[i1] - te[span[0]]) / driver.ratio
    assert abs(real.speed_scale - 1) > 1e-3  # so the check below tells the two speeds apart
    assert speed == pytest.approx(testbed.speed * real.speed_scale, rel=2e-4)
    # the device's motor angle (from the encoder) of every acceleration sample
    motor = np.interp(tx, te, counts) * TWO_PI / cpr / driver.ratio
    # the device plays the run at the speed of its table (2 pi rounded to 5 digits: 6.2832 rad/s)
    run = simulate_state(testbed, testbed.states[0], 1, revolutions=REVS + 2.0, speed=table_speed(testbed.speed),
                         output_rate=20000.0)
    start = TWO_PI * math.ceil((run.motor_angle[0] + FADE) / TWO_PI)  # device angle 0 in the run
    k = REVS - 2  # a late revolution: a speed mismatch of 0.1 % would move it by over a degree
    dev = (motor >= TWO_PI * k) & (motor < TWO_PI * (k + 1))
    assert dev.sum() > 0.9 * 10000 * TWO_PI / testbed.speed
    sim = (run.motor_angle >= start + TWO_PI * k) & (run.motor_angle < start + TWO_PI * (k + 1))
    i_dev = np.flatnonzero(dev)[np.argmax(np.abs(x[dev]))]
    i_sim = np.flatnonzero(sim)[np.argmax(np.abs(run.acc[sim]))]
    crank_dev = driver.phase + driver.ratio * motor[i_dev]
    assert np.mod(crank_dev - run.crank[i_sim] + math.pi, TWO_PI) - math.pi == pytest.approx(0, abs=math.radians(0.3))
    assert x[i_dev] == pytest.approx(run.acc[i_sim], rel=0.15)  # 10 kHz point samples of a ~0.2 ms impact


def test_device_with_a_seed_reproduces_its_stream_and_differs_by_seed(testbed, tables):
    chain = {"aa_filter": "butterworth", "resonance": "25 kHz", "damping": 0.03, "noise": "0.05 m/s^2"}
    one = [b.samples for b in stream(testbed, emulator_config(testbed, STATE, 1, revolutions=REVS, accelerometer=chain),
                                     1.0, rate=10000.0)[1]]
    again = [b.samples for b in stream(testbed, emulator_config(testbed, STATE, 1, revolutions=REVS,
                                                                accelerometer=chain), 1.0, rate=10000.0)[1]]
    two = [b.samples for b in stream(testbed, emulator_config(testbed, STATE, 2, revolutions=REVS, accelerometer=chain),
                                     1.0, rate=10000.0)[1]]
    np.testing.assert_array_equal(np.concatenate(one), np.concatenate(again))
    assert not np.array_equal(np.concatenate(one), np.concatenate(two))


def test_a_mass_changed_in_memory_gets_a_new_table(testbed, cache):
    """The cache key holds the bench's content: a heavier slider in memory is a new model table."""
    from wearbench.hardware.emulators.signal import model_table

    cfg = emulator_config(testbed, STATE, None)
    nominal = model_table(testbed, cfg.truth, testbed.speed)
    bodies = tuple(dataclasses.replace(b, mass=b.mass * 1.5) if b.name == "slider" else b for b in testbed.bodies)
    heavy = dataclasses.replace(testbed, bodies=bodies)
    assert heavy.sha256 == testbed.sha256  # the file it came from is the same
    changed = model_table(heavy, cfg.truth, testbed.speed)
    assert np.sqrt(np.mean((changed.acc - nominal.acc) ** 2)) > 1e-3 * np.abs(nominal.acc).max()
    assert len(list((cache / "emulator").glob("ninebar-testbed-twin-*.npz"))) == 2


def test_the_table_key_covers_every_model_parameter(testbed, tmp_path):
    from wearbench.hardware.emulators.signal import table_key

    truth = emulator_config(testbed, "0.3 mm first wear", 3).truth

    def key(bench=testbed, truth=truth, speed=testbed.speed, **kw):
        return table_key(bench, truth, speed, **{"kind": "run", "revolutions": 40, "settle": 2.0, "rate": 2e4, **kw})

    def contact(bench, **change):
        joints = tuple(dataclasses.replace(j, clearance=dataclasses.replace(
            j.clearance, contact=dataclasses.replace(j.clearance.contact, **change)))
            if j.clearance is not None else j for j in bench.joints)
        return dataclasses.replace(bench, joints=joints)

    def body(**change):
        return dataclasses.replace(testbed, bodies=(dataclasses.replace(testbed.bodies[0], **change),
                                                    *testbed.bodies[1:]))

    worn = tmp_path / "A.npz"
    worn.write_bytes(truth.wear["A"].read_bytes())
    same_file_content = dataclasses.replace(truth, wear={**truth.wear, "A": worn})
    assert key(truth=same_file_content) == key()  # a copy of the file: same content, same table
    assert key(bench=dataclasses.replace(testbed, description="renamed", emulator={})) == key()
    worn.write_bytes(truth.wear["B"].read_bytes())  # other content under the same name
    variants = {
        "surface content": key(truth=same_file_content),
        "mass": key(bench=body(mass=testbed.bodies[0].mass * 1.01)),
        "inertia": key(bench=body(inertia=testbed.bodies[0].inertia * 1.01)),
        "body point": key(bench=body(points={k: (x + 1e-5, y) for k, (x, y) in testbed.bodies[0].points.items()})),
        "ground point": key(bench=dataclasses.replace(testbed, ground_points={
            k: (x, y + 1e-5) for k, (x, y) in testbed.ground_points.items()})),
        "restitution": key(bench=contact(testbed, restitution=0.85)),
        "friction": key(bench=contact(testbed, friction_coefficient=0.12)),
        "exponent": key(bench=contact(testbed, exponent=1.4)),
        "tolerances (the draw)": key(bench=dataclasses.replace(testbed, tolerances=dataclasses.replace(
            testbed.tolerances, mass=0.05))),
        "clearance": key(truth=dataclasses.replace(truth, clearances={"A": 0.31e-3, "B": 0.3e-3})),
        "seed": key(truth=dataclasses.replace(truth, seed=4)),
        "speed": key(speed=testbed.speed * 1.001),
        "revolutions": key(revolutions=41),
        "settle": key(settle=3.0),
        "rate": key(rate=4e4),
    }
    assert len(set(variants.values()) | {key()}) == len(variants) + 1, variants
