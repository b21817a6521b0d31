"""The README and docs/ stay short and whole: the README's length, every relative link,
image and anchor, and the two commands that CI runs exactly as the README says."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]

#: The README's two commands, character for character (.ci/run mirrors the second).
SAMPLE_COMMAND = (
    "python3 -m venv .venv && . .venv/bin/activate && pip install torch==2.13.0 && pip install . "
    "&& jeanscv sample_images/cat.jpg -o out --json"
)
TEST_COMMAND = (
    "python3 -m venv .venv && . .venv/bin/activate && pip install torch==2.13.0 && "
    'pip install -e ".[test]" && python -m pytest -q'
)

_FENCE = re.compile(r"^```.*?^```", re.S | re.M)
_CODE_SPAN = re.compile(r"`[^`\n]*`")
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
_HEADING = re.compile(r"^#{1,6}\s+(.+?)\s*#*\s*$", re.M)


def _prose(text: str) -> str:
    """The text without fenced code blocks and code spans, where brackets are not links."""
    return _CODE_SPAN.sub("", _FENCE.sub("", text))


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*]|<[^>]+>", "", heading).strip().lower()
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def _anchors(path: Path) -> set[str]:
    """Every heading anchor of a page, with GitHub's -1, -2 suffixes for repeats."""
    seen: dict[str, int] = {}
    anchors = set()
    for heading in _HEADING.findall(_FENCE.sub("", path.read_text(encoding="utf-8"))):
        slug = _slug(heading)
        count = seen.get(slug, 0)
        seen[slug] = count + 1
        anchors.add(slug if count == 0 else f"{slug}-{count}")
    return anchors


def _links(path: Path) -> list[str]:
    return _LINK.findall(_prose(path.read_text(encoding="utf-8")))


def test_the_readme_is_short():
    lines = README.read_text(encoding="utf-8").count("\n")
    assert lines <= 260, f"README.md has {lines} lines; the manual belongs in docs/"


def test_the_slug_follows_github():
    assert _slug("How `auto` finds the subject") == "how-auto-finds-the-subject"
    assert (
        _slug("`default`: designed to pass the paper's four rules") == "default-designed-to-pass-the-papers-four-rules"
    )
    assert _slug("The web page: jeanscv serve") == "the-web-page-jeanscv-serve"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_anchor_exists(page):
    broken = []
    for target in _links(page):
        if re.match(r"[a-z][a-z0-9+.-]*:", target):  # http:, https:, mailto:
            continue
        file_part, _, anchor = target.partition("#")
        linked = (page.parent / file_part).resolve() if file_part else page
        if not linked.exists():
            broken.append(f"{target}: no such file")
        elif anchor and linked.suffix == ".md" and anchor not in _anchors(linked):
            broken.append(f"{target}: no heading with this anchor")
    assert not broken, f"{page.relative_to(ROOT)}: " + "; ".join(broken)


def test_the_readme_keeps_the_two_commands():
    readme = README.read_text(encoding="utf-8")
    assert f"```bash\n{SAMPLE_COMMAND}\n```" in readme
    assert f"```bash\n{TEST_COMMAND}\n```" in readme


def test_ci_runs_the_readme_test_command():
    """.ci/run installs what the README's test command installs, in that order, then runs
    the same pytest command."""
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    installs = re.findall(r"^python -m pip install --quiet (?!--upgrade)(.+)$", ci, re.M)
    assert installs == ["torch==2.13.0", '-e ".[test]"']
    assert re.findall(r"pip install (torch==\S+|-e \S+)", TEST_COMMAND) == installs
    assert ci.rstrip().endswith("python -m pytest -q") and TEST_COMMAND.endswith("python -m pytest -q")
