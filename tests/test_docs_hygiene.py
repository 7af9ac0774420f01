"""README.md and docs/*.md state what is true now: no run history (commit hashes, run
ids such as r15, streaks, stop numbers: those belong in commit messages), a README short
enough to be a front door, every doc on its map, and every relative link resolving to a
file (and a heading, when it names one)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.conftest import REPO

README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))
FILES = [README, *DOCS]
README_MAX_LINES = 220

# Words of 7-40 hex digits with a digit and a letter that are not commit hashes. Add a
# token here (with what it is) when a doc needs one.
NOT_HASHES: frozenset[str] = frozenset()

HASH = re.compile(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b", re.IGNORECASE)
RUN_ID = re.compile(r"\br\d+\b")
STREAK = re.compile(r"\bstreaks?\b", re.IGNORECASE)
# "stop 27", "stop-26", "Stop 27": a working session's number; "stop 10 s after" is a
# duration and passes.
STOP_NUMBER = re.compile(
    r"\bstop[ -]\d+\b(?!\s*(?:s|ms|m|%|seconds?|minutes?|times)\b)", re.IGNORECASE
)
# "issue 16", "issues 11 and 16": which issue made a thing is history too (the tracker
# and the commit messages hold it); docs and code comments say what holds now
ISSUE = re.compile(r"\bissues? #?\d+", re.IGNORECASE)
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^(```|~~~)")


def _ids(path: Path) -> list[str]:
    return [path.relative_to(REPO).as_posix()]


def _prose(path: Path) -> list[tuple[int, str]]:
    """The file's lines outside fenced code blocks, numbered from 1."""
    lines, inside = [], False
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if FENCE.match(line.strip()):
            inside = not inside
            continue
        if not inside:
            lines.append((number, line))
    return lines


def history_in(text: str) -> list[str]:
    """What in `text` reads as run history, each as the matched words."""
    found = [m.group(0) for m in HASH.finditer(text) if m.group(0).lower() not in NOT_HASHES]
    for pattern in (RUN_ID, STREAK, STOP_NUMBER, ISSUE):
        found += [m.group(0) for m in pattern.finditer(text)]
    return found


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    seen: dict[str, int] = {}
    out = set()
    for _, line in _prose(path):
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        base = slug(m.group(1))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.add(base if n == 0 else f"{base}-{n}")
    return out


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("merged at `d790d3f` on main", ["d790d3f"]),
        ("upstream df83545f0b17 built", ["df83545f0b17"]),
        ("r15 in benchmarks.md failed", ["r15"]),
        ("the streak of ten runs", ["streak"]),
        ("Streaks of stop 26", ["Streaks", "stop 26"]),
        ("on stop-27's main", ["stop-27"]),
        ("followers stop 10 s after it falls silent", []),
        ("a 5 m threshold, 1e-5 BER, 0xFFFF, deadbeef, 1234567, R = 30 m", []),
        ("VTOL QuadPlane ArduCopter 2026-11-26", []),
        ("the declared state (issue 16) and issues 11", ["issue 16", "issues 11"]),
        ("the issue's check", []),
    ],
)
def test_what_counts_as_run_history(text: str, expected: list[str]) -> None:
    assert sorted(history_in(text)) == sorted(expected)


@pytest.mark.parametrize("path", FILES, ids=_ids)
def test_no_run_history(path: Path) -> None:
    bad = [
        f"{path.relative_to(REPO)}:{number}: {word}"
        for number, line in enumerate(path.read_text().splitlines(), 1)
        for word in history_in(line)
    ]
    assert not bad, "run history belongs in commit messages:\n" + "\n".join(bad)


def test_the_readme_is_a_front_door() -> None:
    lines = README.read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"
    text = README.read_text()
    for command in ("make demo", "make test", "swarm-sim vehicle", "swarm-node run", "gcs status"):
        assert command in text, command
    assert "## Test targets" in text


def test_every_doc_is_on_the_readme_map() -> None:
    linked = {
        (README.parent / m.group(1).split("#")[0]).resolve()
        for _, line in _prose(README)
        for m in LINK.finditer(line)
    }
    missing = [d.name for d in DOCS if d.resolve() not in linked]
    assert not missing, f"docs not linked from README.md: {missing}"


@pytest.mark.parametrize("path", FILES, ids=_ids)
def test_relative_links_resolve(path: Path) -> None:
    broken = []
    for number, line in _prose(path):
        for m in LINK.finditer(line):
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
                continue  # http:, https:, mailto:
            file_part, _, anchor = target.partition("#")
            dest = (path.parent / file_part).resolve() if file_part else path
            if not dest.exists():
                broken.append(f"{path.relative_to(REPO)}:{number}: {target} (no such file)")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                broken.append(f"{path.relative_to(REPO)}:{number}: {target} (no such heading)")
    assert not broken, "\n".join(broken)


SOURCES = ("swarm_proto", "swarm_node", "radio_gateway", "gcs_cli", "swarm_sim", "bench", "tests")


def test_no_issue_numbers_in_code() -> None:
    """Comments and docstrings say why, not which issue asked for it."""
    bad = [
        f"{path.relative_to(REPO)}:{number}: {m.group(0)}"
        for pkg in SOURCES
        for path in sorted((REPO / pkg).rglob("*.py"))
        if path.name != "test_docs_hygiene.py"
        for number, line in enumerate(path.read_text().splitlines(), 1)
        for m in ISSUE.finditer(line)
    ]
    assert not bad, "issue numbers in code:\n" + "\n".join(bad)
