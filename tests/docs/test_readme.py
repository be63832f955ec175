"""The README is a short introduction: at most 250 lines, no version history, the test command
that ``.ci/run`` reads, the way to estimate one's own session, and no citation of files a user's clone
does not have."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.no_kernels

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
HISTORY = ("earlier version", "version before", "this version", "versions ago")


def test_short_and_without_version_history():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    found = [p for p in HISTORY if p in text.lower()]
    assert not found, f"version-history phrases in the README: {found}"


def test_the_test_command_block_is_what_ci_runs():
    """``.ci/run`` takes the command from between the markers with sed; the same extraction here must
    give the install-and-pytest command."""
    block = subprocess.run(["bash", "-c", ("sed -n '/<!-- test-command -->/,/<!-- \\/test-command -->/p' README.md "
                            "| sed -n '/^```/,/^```/p' | sed '1d;$d'")], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.strip()
    assert block == "python3 -m venv .venv && .venv/bin/pip install -e '.[test]' && .venv/bin/pytest -n auto"


def test_the_way_to_estimate_ones_own_session_is_on_the_readme():
    text = README.read_text(encoding="utf-8")
    heading = re.search(r"^## .*[Ee]stimate.*$", text, re.MULTILINE)
    assert heading, "no README section on estimating a session"
    assert re.search(r"^wearbench estimate \S+\.mcap", text[heading.end():], re.MULTILINE)


def test_no_citation_of_the_shared_folder():
    """``shared/reference/`` is not in a user's clone: the docs cite their own parameters page."""
    files = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    citing = [str(p.relative_to(ROOT)) for p in files if "shared/reference" in p.read_text(encoding="utf-8")]
    assert not citing, f"files citing shared/reference/: {citing}"
    assert (ROOT / "docs" / "explanation" / "ninebar-parameters.md").is_file()
