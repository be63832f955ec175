"""Issue 44: an emulated bench's truth against a session's labels. ``record --clearance/--wear`` on the
in-process ``sim`` emulator sets its truth (the session labelled worn is worn: its signal differs and the
truth marks it records differ); a serial emulator, whose truth is set where it runs, refuses labels it
does not play; the marks tell a host whether a claim holds, not the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest
from wearbench.acquisition.session_file import read_session
from wearbench.bench.load import load_bench, shipped_bench
from wearbench.cli import main
from wearbench.hardware.emulators.config import EmulatorConfig, emulator_config
from wearbench.hardware.protocol.truth import announce, clearance_mark, read_marks, wear_mark
from wearbench.model.surfaces import JointSurfaces

pytestmark = pytest.mark.timeout(300)

FOURBAR = shipped_bench("fourbar")


@pytest.fixture(scope="module")
def fourbar():
    return load_bench(FOURBAR)


@pytest.fixture
def worn(tmp_path):
    """Worn surfaces for the fourbar's joint R: 0.1 mm off the whole bearing (a larger clearance, in effect)."""
    return JointSurfaces(np.full(100, 1e-4), np.zeros(100), label="test wear").save(tmp_path / "worn-R.npz")


def test_marks_check_a_claim_without_telling_the_truth():
    marks = {"A": (clearance_mark("b", "A", 0.3e-3), wear_mark("b", "A", None)),
             "B": (clearance_mark("b", "B", 0.3e-3), wear_mark("b", "B", "ab" * 32))}
    name = announce("b", marks)
    assert name.startswith("wearbench emulator b truth ") and read_marks(name) == marks
    assert "0.3" not in name and "new" not in name
    assert clearance_mark("b", "A", 0.3e-3) == clearance_mark("b", "A", 0.30000000000000004e-3)
    assert clearance_mark("b", "A", 0.3e-3) not in (clearance_mark("b", "A", 0.6e-3), clearance_mark("b", "B", 0.3e-3))
    assert read_marks("wearbench emulator b") is None and read_marks("my lab's MCU, truth A=123456/abcdef") is None
    assert announce("b", {f"joint{i}": ("0" * 6, "1" * 6) for i in range(20)}) == "wearbench emulator b"  # too long


def test_a_truth_labelled_as_it_is_stays_itself_and_names_the_state_it_becomes(fourbar, worn):
    truth = EmulatorConfig.from_bench(fourbar).truth
    assert truth.joints(fourbar) == {"R": (pytest.approx(0.3e-3), None)}
    assert truth.labelled(fourbar, {"R": 0.3e-3}, {"R": None}) is truth
    wider = truth.labelled(fourbar, {"R": 0.6e-3}, {})
    assert wider.wear_stage == "0.6 mm new" and wider.seed == truth.seed and wider.marks(fourbar) != truth.marks(fourbar)
    worn_truth = truth.labelled(fourbar, {}, {"R": worn})
    assert worn_truth.wear_stage == "as recorded" and worn_truth.joints(fourbar)["R"][1] == worn.resolve()
    assert worn_truth.marks(fourbar)["R"][0] == truth.marks(fourbar)["R"][0]  # the clearance is the same
    with pytest.raises(ValueError, match="no clearance joint"):
        truth.labelled(fourbar, {"Q": 0.3e-3}, {})


def _record(bench, out, *labels, config=None, backend="sim", options=()):
    argv = ["record", str(bench), "--backend", backend, "--cycles", "2", "--out", str(out), *labels]
    if backend == "sim":
        argv += ["--option", "speedup=inf", "--option", f"config={config}"]
    for option in options:
        argv += ["--option", option]
    return main(argv)


def test_a_worn_label_really_wears_the_sim_emulator(fourbar, worn, tmp_path, capsys):
    """The same emulator config (its truth: 0.3 mm new) recorded with the labels new and worn: the worn
    session is the worn bench (its acceleration differs, the truth marks it recorded differ), and the
    command says the labels set the truth."""
    config = tmp_path / "twin.json"  # the model's twin, one settling revolution: seconds, not minutes
    config.write_text(json.dumps({"settle": 1, "truth": {"twin": True, "state": "0.3 mm new"}}))
    sessions = {}
    for label in ("new", str(worn)):
        out = tmp_path / f"{'new' if label == 'new' else 'worn'}.mcap"
        assert _record(FOURBAR, out, "--clearance", "R=0.3mm", "--wear", f"R={label}", config=config) == 0
        said = [x for x in capsys.readouterr().out.splitlines() if x.startswith("wearbench record:")]
        sessions[label] = read_session(out), said
    (new, said_new), (worn_session, said_worn) = sessions["new"], sessions[str(worn)]
    assert said_new == [("wearbench record: the sim emulator plays what --clearance/--wear say, as --option "
                         f"config={config} already had it: R 0.3 mm new; the model's twin")]
    assert len(said_worn) == 1 and "truth set from --clearance/--wear: it plays R 0.3 mm worn (worn-R.npz)" in \
        said_worn[0] and "instead of --option config" in said_worn[0]
    # the recorded truth marks: the clearance's the same, the wear's not, and both are what the labels claim
    marks_new, marks_worn = (read_marks(s.metadata["hardware"]["truth"])["R"] for s in (new, worn_session))
    assert marks_new[0] == marks_worn[0] and marks_new[1] != marks_worn[1]
    expected = emulator_config(fourbar, None, None).truth.labelled(fourbar, {}, {"R": worn}).marks(fourbar)["R"]
    assert marks_worn == expected
    # the signal: the same crank angles, another acceleration (a 0.1 mm wider bearing hits harder)
    n = min(len(new.acceleration), len(worn_session.acceleration))
    a, b = (s.acceleration["acc"].to_numpy()[:n] for s in (new, worn_session))
    assert np.sqrt(np.mean((a - b) ** 2)) > 0.5 * np.sqrt(np.mean(a**2))
    assert np.abs(b).max() > np.abs(a).max()


@pytest.fixture
def serial_fourbar():
    """The fourbar's serial emulator in its own process, its truth "0.3 mm new" (no signal: only its
    truth matters here)."""
    from wearbench.hardware.emulators.serial_server import start_serial_emulator

    procs = []

    def start():
        proc, port = start_serial_emulator(load_bench(FOURBAR), {"signal": "none", "truth": {"state": "0.3 mm new"}})
        procs.append(proc)
        return port

    yield start
    for p in procs:
        p.terminate()
        p.wait(timeout=30)


@pytest.mark.parametrize("labels, refused", [
    (["--wear", "R=WORN"], ("--wear R=WORN: refused: the emulated bench behind the serial backend "
                            "(wearbench emulator fourbar) has another wear at R")),
    (["--clearance", "R=0.6mm", "--wear", "R=new"], ("--clearance R=0.6mm: refused: the emulated bench behind "
                                                     "the serial backend (wearbench emulator fourbar) has another "
                                                     "clearance")),
])
def test_a_serial_emulator_refuses_a_label_it_does_not_play(labels, refused, serial_fourbar, worn, tmp_path, capsys):
    port = serial_fourbar()
    out = tmp_path / "s.mcap"
    labels = [x.replace("WORN", str(worn)) for x in labels]
    assert _record(FOURBAR, out, *labels, backend="serial", options=[f"port={port}"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and refused.replace("WORN", str(worn)) in err[0], err
    assert "a host cannot change it" in err[0] and "record without" in err[0]
    assert not out.exists()


def test_a_serial_emulator_records_labels_it_plays(serial_fourbar, tmp_path, capsys):
    port = serial_fourbar()
    out = tmp_path / "s.mcap"
    assert main(["record", str(FOURBAR), "--backend", "serial", "--option", f"port={port}", "--speed", "60",
                 "--cycles", "1", "--settle", "0.1s", "--clearance", "R=0.3mm", "--wear", "R=new",
                 "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert ("wearbench record: --clearance/--wear agree with the truth of the emulated bench behind the serial "
            "backend (wearbench emulator fourbar) (checked by its marks)") in said
    session = read_session(out)
    assert session.clearances == {"R": pytest.approx(0.3e-3)} and session.wear_state == {"R": "new"}
