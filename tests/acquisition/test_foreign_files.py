"""Files that are not wearbench sessions get one clear line and exit 2, never a traceback or a
report that treats them as recoverable sessions."""

from __future__ import annotations

import os

import pytest
from mcap.writer import Writer
from wearbench.cli import main

pytestmark = pytest.mark.no_kernels


@pytest.mark.parametrize("content", [b"", os.urandom(4096)], ids=["empty", "random"])
def test_inspect_a_file_that_is_not_mcap(tmp_path, capsys, content):
    path = tmp_path / "s.mcap"
    path.write_bytes(content)
    assert main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err and "not an MCAP file" in err


def test_a_foreign_mcap_reusing_the_acceleration_topic(tmp_path, capsys):
    path = tmp_path / "foreign.mcap"
    with open(path, "wb") as fh:
        w = Writer(fh)
        w.start(profile="", library="someone else")
        sid = w.register_schema(name="other.Vector3", encoding="jsonschema", data=b"{}")
        cid = w.register_channel("/acceleration", "json", sid)
        for i in range(3):
            w.add_message(cid, log_time=i, publish_time=i, data=b'{"x": 1, "y": 2, "z": 3}')
        w.finish()
    assert main(["inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/acceleration" in err and "other.Vector3" in err
