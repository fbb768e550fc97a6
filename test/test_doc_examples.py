"""README.md, docs/*.md and the lab record (research/*.md) cannot rot: their Python examples run, the
commands and scripts their bash examples name exist, the source files they name exist, their relative
links (and #anchors) lead somewhere, and the README's results table holds its recorded runs' figures.

A Python block fenced as ```python no-run is skipped; use it only for code that needs what this
machine cannot have (a live ROS graph, a robot, a display), and say why next to the block.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import pytest

from gwr_predictor.commands.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "research").glob("*.md"))]
FENCE = re.compile(r"^```(\w[\w-]*)?([^\n]*)\n(.*?)^```", re.MULTILINE | re.DOTALL)
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)|!\[[^\]]*\]\(([^)\s]+)\)|<img [^>]*src=\"([^\"]+)\"")
HEADING = re.compile(r"^#{1,6} (.+?)\s*$", re.MULTILINE)
NODES = ("skeleton_source", "angle_extractor", "arm_predictor", "delay_compensator", "nao_sim", "bag_recorder",
         "bag_player", "hri_bodies")


def rel(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def blocks(page: Path, language: str) -> list[tuple[int, str, str]]:
    """(line, info after the language, body) of every fenced block of `language` on the page."""
    text = page.read_text(encoding="utf-8")
    found = []
    for match in FENCE.finditer(text):
        if (match.group(1) or "") == language:
            found.append((text.count("\n", 0, match.start()) + 1, match.group(2).strip(), match.group(3)))
    return found


def python_blocks() -> list:
    return [pytest.param(page, line, body, id=f"{rel(page)}:{line}",
                         marks=[pytest.mark.skip(reason="marked no-run")] if "no-run" in info else [])
            for page in PAGES for line, info, body in blocks(page, "python")]


@pytest.mark.parametrize(("page", "line", "body"), python_blocks())
def test_python_examples_run(page, line, body, capsys):
    code = compile(body, f"{rel(page)}:{line}", "exec")
    exec(code, {"__name__": "__doc_example__"})  # a fresh namespace per block, as a reader would start


def commands_named(script: str) -> list[tuple[str, str]]:
    """(kind, name) for each `gwr-predictor NAME`, `scripts/NAME` and `ros2 run gwr_predictor NAME` in a bash block."""
    named = []
    for raw in script.splitlines():
        line = raw.split(" #", 1)[0].strip()
        if not line or line.startswith("#"):
            continue
        try:
            words = shlex.split(line, comments=True)
        except ValueError:  # an unbalanced quote in a line continued on the next: plain split is enough here
            words = line.split()
        for i, word in enumerate(words):
            nxt = words[i + 1] if i + 1 < len(words) else ""
            if word == "gwr-predictor" and nxt and not nxt.startswith("-"):
                named.append(("command", nxt))
            elif re.fullmatch(r"(\./)?scripts/[\w.-]+", word):
                named.append(("script", word.removeprefix("./")))
            elif word == "run" and i >= 1 and words[i - 1] == "ros2" and nxt == "gwr_predictor" and i + 2 < len(words):
                named.append(("node", words[i + 2]))
    return named


def bash_commands() -> list:
    return [pytest.param(kind, name, id=f"{rel(page)}:{line}:{name}")
            for page in PAGES for line, _, body in blocks(page, "bash") for kind, name in commands_named(body)
            if "<" not in name]


@pytest.mark.parametrize(("kind", "name"), bash_commands())
def test_bash_examples_name_what_exists(kind, name):
    if kind == "command":
        assert name in COMMANDS, f"'gwr-predictor {name}' is not a command; the commands are {sorted(COMMANDS)}"
    elif kind == "script":
        assert (ROOT / name).is_file(), f"{name} does not exist"
    else:
        assert name in NODES, f"'ros2 run gwr_predictor {name}': no such node; the nodes are {NODES}"


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces as hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    seen: dict[str, int] = {}
    found = set()
    text = FENCE.sub("", page.read_text(encoding="utf-8"))
    for match in HEADING.finditer(text):
        base = slug(match.group(1))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def links() -> list:
    found = []
    for page in PAGES:
        text = FENCE.sub("", page.read_text(encoding="utf-8"))
        for match in LINK.finditer(text):
            target = next(group for group in match.groups() if group)
            if not re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto: are not ours to check
                found.append(pytest.param(page, target, id=f"{rel(page)}->{target}"))
    return found


@pytest.mark.parametrize(("page", "target"), links())
def test_relative_links_resolve(page, target):
    path, _, anchor = target.partition("#")
    destination = (page.parent / path).resolve() if path else page
    assert destination.exists(), f"{rel(page)} links to {target}, which does not exist"
    if anchor and destination.suffix == ".md":
        assert anchor in anchors(destination), f"{rel(page)} links to {target}: no such heading in {destination.name}"


CODE_PATH = re.compile(r"`((?:[\w.-]+/)*[\w-]+\.(?:py|sh|urdf|rviz))\b")
SOURCE_ROOTS = (ROOT, ROOT / "gwr_predictor", ROOT / "research")
SOURCE_DIRS = ("gwr_predictor", "nodes", "research", "scripts", "test", "launch")


def code_paths() -> list:
    """Every source file a page names in backticks: `dir/name.py` from the repository, the library or
    research/; a bare `name.py` anywhere in the source folders."""
    found = []
    for page in PAGES:
        for match in CODE_PATH.finditer(page.read_text(encoding="utf-8")):
            found.append(pytest.param(match.group(1), id=f"{rel(page)}:{match.group(1)}"))
    return found


@pytest.mark.parametrize("path", code_paths())
def test_named_source_files_exist(path):
    if path.startswith(("share/", "install/")):
        pytest.skip("an installed location, made by colcon build")
    path = path.replace("gwr_predictor/nodes/", "nodes/")  # the nodes install as gwr_predictor.nodes
    if "/" in path:
        assert any((root / path).is_file() for root in SOURCE_ROOTS), f"{path} is in none of {SOURCE_ROOTS}"
    else:
        assert any(any((ROOT / folder).rglob(path)) for folder in SOURCE_DIRS), f"no {path} in {SOURCE_DIRS}"


def test_the_pages_have_examples_to_check():
    """Guards the extraction itself: a broken fence pattern would otherwise pass with nothing checked."""
    assert python_blocks() and bash_commands() and links() and code_paths()


def _to_hold(stats: dict, method: str) -> float:
    """MAE at the last step as a share of holding the pose's, from a results.json's per-method figures."""
    return stats[method]["mae"][-1] / stats["hold"]["mae"][-1]


#: The README's results table, column by column: the recorded run it quotes and how to read a method there.
RESULT_COLUMNS = (
    ("repeats", lambda r, m: r["ratio_to_hold"]["pooled"][m]),
    ("real", lambda r, m: _to_hold(r["one_pass"]["pooled"], m)),
    ("compare", lambda r, m: _to_hold(r["conditions"]["heldout_repetitions/frozen"], m)),
    ("compare", lambda r, m: _to_hold(r["conditions"]["heldout_subjects/frozen"], m)),
)


def readme_results_rows() -> list[tuple[str, list[str]]]:
    """(registry name, cells) of each method row of the README's results table ("hold the last pose": hold)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Results\n", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("|") or len(cells) != len(RESULT_COLUMNS) + 1 or set(cells[1]) <= set("-"):
            continue
        name = re.search(r"`(\w+)`", cells[0])
        if name or cells[0].startswith("hold"):
            rows.append((name.group(1) if name else "hold", cells[1:]))
    return rows


def test_the_readme_results_table_is_the_recorded_runs():
    """Every figure of the README's table is its recorded run's (research/results/*/results.json), to the
    three decimals shown: a re-run that moves a figure moves the table, or this fails."""
    runs = {name: json.loads((ROOT / "research" / "results" / name / "results.json").read_text())["results"]
            for name in {run for run, _ in RESULT_COLUMNS}}
    rows = readme_results_rows()
    assert {"hold", "rls_ar", "gwr_experts"} <= {name for name, _ in rows}
    for name, cells in rows:
        for cell, (run, read) in zip(cells, RESULT_COLUMNS, strict=True):
            assert cell.strip("*") == f"{read(runs[run], name):.3f}", f"README row {name}, run {run}"
