"""mkdocs hooks for the user guide (``mkdocs.yml``).

The guide links the benchmarks' results pages and the model cards where they live in the
repository (``../benchmarks/results/fit_speed.md``), so that the links work in a checkout
and on a code host.  mkdocs only knows files under ``docs/``: these hooks add those pages to
the site under ``repo/`` and point the links there, so ``mkdocs build --strict`` checks
them like any other link.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

from mkdocs.structure.files import File, InclusionLevel

ROOT = Path(__file__).resolve().parent.parent
#: The repository pages outside docs/ that the guide may link.
PAGES = ("benchmarks/results/*.md", "nets/models/README.md", "nets/models-backlit/README.md")
PREFIX = "repo/"
LINK = re.compile(r"(\]\()([^)\s#]+)([^)]*\))")


def included() -> set[str]:
    return {p.relative_to(ROOT).as_posix() for g in PAGES for p in ROOT.glob(g)}


def on_files(files, config):
    for rel in sorted(included()):
        files.append(File.generated(config, PREFIX + rel, abs_src_path=str(ROOT / rel),
                                    inclusion=InclusionLevel.NOT_IN_NAV))
    return files


def on_page_markdown(markdown, page, config, files):
    src = page.file.src_uri
    in_repo = src[len(PREFIX):] if src.startswith(PREFIX) else "docs/" + src
    repo_dir, site_dir = posixpath.dirname(in_repo), posixpath.dirname(src) or "."
    pages = included()

    def fix(m: re.Match) -> str:
        url = m.group(2)
        if "://" in url or url.startswith(("/", "mailto:")):
            return m.group(0)
        target = posixpath.normpath(posixpath.join(repo_dir, url))
        if target in pages:
            return m.group(1) + posixpath.relpath(PREFIX + target, site_dir) + m.group(3)
        if target.startswith("docs/"):
            return m.group(1) + posixpath.relpath(target[len("docs/"):], site_dir) + m.group(3)
        return m.group(0)  # left as is: mkdocs reports it if it is not a page of the site

    return LINK.sub(fix, markdown)
