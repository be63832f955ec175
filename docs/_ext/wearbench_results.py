"""Results pages: every ``results/data/*.json`` file is one page of the documentation.

A benchmark script run with ``--json PATH`` writes one result in the schema of
``results/schema.json`` (``wearbench-result/1``: the question, the script and exact command, the
version and commit, the seeds, tables with columns and units, notes). This extension registers
``.json`` under ``results/data/`` as a source type: Sphinx reads each such file as a document, which
:func:`render` turns into MyST Markdown (title = the question; the findings, the tables, how to
reproduce) for the MyST parser. No page is typed by hand and nothing is generated into the source
tree: removing a JSON file removes its page. A file that breaks the schema (or a row whose length is
not its table's column count) is a build warning, an error under ``-W``.

``render`` is also what ``tests/docs/test_results_pages.py`` checks the built pages against.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from myst_parser.parsers.sphinx_ import MystParser
from sphinx.util import logging

logger = logging.getLogger(__name__)

SCHEMA_PATH = Path(__file__).resolve().parent.parent / "results" / "schema.json"
DATA = "results/data/"  # documents under this folder with a .json suffix are results


def schema() -> dict:
    return json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))


def problems(result: Any) -> list[str]:
    """What is wrong with ``result`` against the schema and the rules it cannot state (empty: none)."""
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema())
    found = [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}"
             for e in sorted(validator.iter_errors(result), key=lambda e: list(map(str, e.absolute_path)))]
    if found:
        return found
    for i, table in enumerate(result["tables"]):
        n = len(table["columns"])
        for j, row in enumerate(table["rows"]):
            if len(row) != n:
                found.append(f"tables/{i}/rows/{j}: {len(row)} values for {n} columns")
        for k, column in enumerate(table["columns"]):
            fmt = column.get("format")
            numbers = [v for v in (row[k] for row in table["rows"] if len(row) == n)
                       if isinstance(v, (int, float)) and not isinstance(v, bool)]
            for v in numbers if fmt else ():
                try:
                    format(v, fmt)
                except ValueError as exc:
                    found.append(f"tables/{i}/columns/{k}/format: {fmt!r} for {v!r}: {exc}")
                    break
    return found


def cell(value: Any, fmt: str | None) -> str:
    """One value as the page shows it."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, float)):
        if isinstance(value, float) and not math.isfinite(value):
            return str(value)
        return format(value, fmt) if fmt else str(value)
    return str(value)


def _md(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return str(text).replace("\\", "\\\\").replace("|", "\\|").replace("\n", " ")


def heading(column: dict) -> str:
    unit = column.get("unit")
    return f"{column['label']} ({unit})" if unit else column["label"]


def render(result: dict, source: str) -> str:
    """The MyST Markdown page of one result; ``source`` names its JSON file on the page."""
    out = [f"# {result['question']}", ""]
    findings = result.get("findings") or []
    if findings:
        out += [f"- {f}" for f in findings] + [""]
    for table in result["tables"]:
        out += [f"## {table['title']}", ""]
        if table.get("description"):
            out += [table["description"], ""]
        columns = table["columns"]
        out.append("| " + " | ".join(_md(heading(c)) for c in columns) + " |")
        out.append("|" + "|".join("---" for _ in columns) + "|")
        for row in table["rows"]:
            out.append("| " + " | ".join(_md(cell(v, c.get("format"))) for v, c in zip(row, columns)) + " |")
        out.append("")
    notes = result.get("notes") or []
    if notes:
        out += ["## Notes", ""] + [f"- {n}" for n in notes] + [""]
    b, v = result["benchmark"], result["version"]
    commit = v["commit"] or "no git checkout"
    state = {True: " with uncommitted changes", False: "", None: ""}[v["dirty"]]
    seeds = result["seeds"]
    out += ["## Reproduce it", "", "From the repository root:", "", "```sh", b["command"], "```", ""]
    out.append(f"- Benchmark: `{b['script']}`")
    out.append(f"- Version: wearbench {v['wearbench']}, commit `{commit}`{state}")
    if seeds:
        out.append("- Seeds: " + "; ".join(f"{k} {_seed(s)}" for k, s in seeds.items()))
    else:
        out.append("- Seeds: none (the run draws nothing at random)")
    ran = f"- Generated: {result['generated']}"
    env = result.get("environment") or {}
    if env:
        where = ", ".join(x for x in (env.get("processor"), f"{env['cpus']} cores" if env.get("cpus") else None,
                                      env.get("platform"), f"Python {env['python']}" if env.get("python") else None) if x)
        ran += f" on {where}"
        if env.get("load_average"):
            ran += " (load average " + " / ".join(f"{x:.1f}" for x in env["load_average"]) + ")"
    if b.get("wall_s") is not None:
        ran += f"; {b['wall_s']:.0f} s wall" + (f", {b['cpu_s']:.0f} s CPU" if b.get("cpu_s") is not None else "")
    out += [ran, f"- Data: `docs/{source}`", ""]
    return "\n".join(out)


def _seed(value: Any) -> str:
    if isinstance(value, list):
        return ", ".join(str(x) for x in value)
    return str(value)


class ResultParser(MystParser):
    """A ``results/data/*.json`` file, read as the MyST page :func:`render` makes of it."""

    supported = ("wearbench-result",)

    def parse(self, inputstring: str, document) -> None:
        env = document.settings.env
        source = env.doc2path(env.docname, False)
        env.note_dependency(str(SCHEMA_PATH))  # a changed schema or renderer re-renders every result
        env.note_dependency(__file__)
        try:
            result = json.loads(inputstring)
        except json.JSONDecodeError as exc:
            logger.warning("%s: not JSON: %s", source, exc, location=env.docname)
            return super().parse(f"# {Path(source).stem}\n\nThis result file is not valid JSON.\n", document)
        found = problems(result)
        if found:
            for p in found:
                logger.warning("%s: does not follow results/schema.json: %s", source, p, location=env.docname)
            return super().parse(f"# {Path(source).stem}\n\nThis result file does not follow the schema.\n", document)
        return super().parse(render(result, str(source)), document)


def _only_results_json(app, config) -> None:
    """JSON elsewhere in docs/ is data, not a page: exclude every .json outside results/data/."""
    src = Path(app.srcdir)
    for path in src.rglob("*.json"):
        rel = path.relative_to(src).as_posix()
        if not rel.startswith(DATA) and not rel.startswith("_build/") and rel not in config.exclude_patterns:
            config.exclude_patterns.append(rel)


def setup(app):
    app.add_source_suffix(".json", "wearbench-result")
    app.add_source_parser(ResultParser)
    app.connect("config-inited", _only_results_json)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
