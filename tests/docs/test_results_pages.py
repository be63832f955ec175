"""Every results page comes from a committed JSON file written by a named benchmark command.

- The results folder holds no page typed by hand: only ``index.md``, ``schema.json`` and ``data/*.json``.
- Every JSON file follows the schema, names a script that exists and a command that runs it, and is
  tracked by git (committed, or at least added).
- The built site has exactly one page per JSON file, and every number on a page's main content
  appears in its JSON file (the page is regenerated from it, never annotated).
- A file that breaks the schema fails the build (``-W``): the renderer's check catches each rule.
"""

from __future__ import annotations

import copy
import json
import re
import shlex
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.no_kernels]  # builds the documentation first (CI runs it)

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "docs" / "results"
DATA = RESULTS / "data"


def results() -> list[Path]:
    return sorted(DATA.glob("*.json"))


def test_the_results_folder_holds_no_hand_written_page():
    files = {p.relative_to(RESULTS).as_posix() for p in RESULTS.rglob("*") if p.is_file()}
    allowed = {"index.md", "schema.json"} | {p.relative_to(RESULTS).as_posix() for p in results()}
    assert files == allowed, f"files under docs/results/ that are not results data: {sorted(files - allowed)}"
    assert results(), "no result yet: at least one benchmark writes its JSON under docs/results/data/"


@pytest.mark.parametrize("path", results(), ids=lambda p: p.stem)
def test_each_result_follows_the_schema_and_names_its_command(path):
    pytest.importorskip("jsonschema")
    import wearbench_results

    result = json.loads(path.read_text(encoding="utf-8"))
    assert wearbench_results.problems(result) == []
    script = result["benchmark"]["script"]
    assert (ROOT / script).is_file(), f"{path.name}: {script} does not exist"
    words = shlex.split(result["benchmark"]["command"])
    module = ".".join(Path(script).with_suffix("").parts)
    assert words[:3] == ["python", "-m", module], f"{path.name}: the command does not run {script}: {words}"
    assert "--json" in words, f"{path.name}: the command does not write the JSON: {words}"
    checkout = subprocess.run(["git", "rev-parse", "--git-dir"], cwd=ROOT, capture_output=True, check=False)
    if checkout.returncode == 0:  # outside a git checkout (an unpacked sdist) there is nothing to ask
        tracked = subprocess.run(["git", "ls-files", "--error-unmatch", str(path)], cwd=ROOT, capture_output=True,
                                 check=False)
        assert tracked.returncode == 0, f"{path.name} is not committed (git add it)"


class _Main(HTMLParser):
    """The text of a page's <main> (article) content, without the site's navigation."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.depth = 0
        self.parts: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag == "article" or self.depth:
            self.depth += 1

    def handle_endtag(self, tag):
        if self.depth:
            self.depth -= 1

    def handle_data(self, data):
        if self.depth:
            self.parts.append(data)


NUMBER = re.compile(r"(?<![\w.])[-+]?\d[\d,]*(?:\.\d+)?(?:e[-+]?\d+)?")


def test_one_page_per_result_and_every_number_from_its_json(docs_html):
    pytest.importorskip("jsonschema")
    import wearbench_results

    pages = sorted((docs_html / "results" / "data").glob("*.html"))
    assert [p.stem for p in pages] == [p.stem for p in results()], "results pages and JSON files differ"
    for page, path in zip(pages, results(), strict=True):
        result = json.loads(path.read_text(encoding="utf-8"))
        main = _Main()
        main.feed(page.read_text(encoding="utf-8"))
        text = " ".join(main.parts)
        assert result["question"] in text
        rendered = wearbench_results.render(result, f"results/data/{path.name}")
        corpus = rendered + json.dumps(result)
        for table in result["tables"]:
            for row in table["rows"]:
                for value, column in zip(row, table["columns"], strict=True):
                    assert wearbench_results.cell(value, column.get("format")) in text, (path.name, value)
        strays = [n for n in NUMBER.findall(text) if n not in corpus]
        assert not strays, f"{page.name}: numbers not from {path.name}: {strays[:20]}"


def _float_column(result: dict) -> int:
    """The first column of the first table holding a number with a fraction."""
    rows = result["tables"][0]["rows"]
    return next(k for k in range(len(rows[0])) if any(isinstance(r[k], float) and r[k] % 1 for r in rows))


def test_a_broken_result_is_refused():
    """Each rule of the renderer's check fails on a result that breaks it (and passes the real ones)."""
    pytest.importorskip("jsonschema")
    import wearbench_results

    good = json.loads(results()[0].read_text(encoding="utf-8"))
    assert wearbench_results.problems(good) == []
    cases = {
        "no question": lambda r: r.pop("question"),
        "a script outside benchmarks/": lambda r: r["benchmark"].__setitem__("script", "scratch/x.py"),
        "a row too short": lambda r: r["tables"][0]["rows"][0].pop(),
        "a column without a label": lambda r: r["tables"][0]["columns"][0].pop("label"),
        "no commit field": lambda r: r["version"].pop("commit"),
        "a format that does not fit the values": lambda r: r["tables"][0]["columns"][_float_column(r)].__setitem__(
            "format", "d"),
        "an unknown field": lambda r: r.__setitem__("comment", "typed by hand"),
    }
    for name, breaks in cases.items():
        bad = copy.deepcopy(good)
        breaks(bad)
        assert wearbench_results.problems(bad), f"not refused: {name}"
