"""The README and the user guide (docs/*.md) link only files that exist, and the README stays
short.  Links to the web are not checked; `mkdocs build --strict` (.ci/run) checks the
site's links and anchors."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: [text](target) and ![alt](target); the target up to a space, ')' or '#'.
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s#]*)[^)]*\)")


def local_links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
    return [t for t in LINK.findall(text) if t and "://" not in t and not t.startswith("mailto:")]


def test_pages_found():
    assert len(PAGES) > 5


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_links_exist(page):
    missing = [t for t in local_links(page) if not (page.parent / t).exists()]
    assert not missing, f"{page.relative_to(ROOT)} links files that do not exist: {missing}"


def test_links_found():
    """The checker sees the README's links to results pages and figures."""
    links = local_links(ROOT / "README.md")
    assert any(t.startswith("benchmarks/results/") for t in links)
    assert any(t.startswith("docs/figures/") for t in links)


def test_readme_short():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines <= 160, f"README.md has {lines} lines (at most 160)"


def figures() -> list[str]:
    """The committed figures (all of docs/figures outside a git checkout)."""
    try:
        out = subprocess.run(["git", "ls-files", "docs/figures"], cwd=ROOT, check=True,
                             capture_output=True, text=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        out = []
    return sorted(Path(f).name for f in out) or sorted(
        f.name for f in (ROOT / "docs" / "figures").iterdir())


def test_figures_referenced():
    """Every committed figure in docs/figures is shown by the README or a guide page (the
    rest stays in git history)."""
    text = "\n".join(p.read_text(encoding="utf-8") for p in PAGES)
    unused = [f for f in figures() if f"figures/{f}" not in text]
    assert not unused, f"figures no page shows: {unused}"
