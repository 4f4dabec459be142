"""The shape of the code: how often the pieces issue 18 found repeated are written, and the
import graph between the parts (core ``ipm``, ``render``, ``nets``, ``refine``,
``benchmarks``, the command line ``cli``) from the AST, lazy imports inside functions
included.  ``--root`` reads another checkout, so two commits can be compared.

    python -m ipm.benchmarks.code_shape [--root DIR] [--out FILE]
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import tokenize
from collections import Counter
from pathlib import Path

FOLDERS = {"ipm": "core", "render": "render", "nets": "nets", "refine": "refine",
           "benchmarks": "benchmarks"}
#: (what, regex): each line of the package sources that matches counts once.
PATTERNS = (
    ("photo pixel size to scene pitch (`pixel_size * scale / PIXEL_SIZE_MM`)",
     r"pixel_size\w* \* [\w.]+ / PIXEL_SIZE_MM"),
    ("\"photo too small\" messages", r"is too small: at|too small for the nets"),
    ("photo inversions (`1 - image`)", r"\b1 - (image|img|self\.image)\b"),
    ("Gaussian blur calls of a library (one is the loss statistics' own, refine/stats.py)",
     r"\bgaussian\(|gaussian_blur2d\("),
    ("sRGB -> linear -> blur -> sRGB written out", r"defocus\(srgb_to_linear\("),
    ("manifest file name constants", r"^MANIFEST = "),
    ("manifest readers (`def read_manifest`)", r"def read_manifest"),
    ("photo and dataset-record types", r"^class Record\b|^class Photo\b"),
    ("output checks (file or folder)", r"def check_output|def _prepare_folder|def prepare_folder"
     r"|check_writable_folder\(out\.parent|cannot create report folder"),
    ("imports of `ipm.cli` (ipm/__main__.py's is the entry point)",
     r"from ipm\.cli import|import ipm\.cli"),
    ("continuous raw-parameter lists", r"\"m\", \"alpha\", \"r_x\", \"r_y\", \"alpha_ply\", "
     r"\"R_ply\"|\"alpha\", \"alpha_ply\", \"R_ply\", \"r_x\", \"r_y\""),
    ("raw <-> normalised formulas", r"- iv\.lo\) / iv\.width|iv\.lo \+ .*\* iv\.width|"
     r"lo \+ np\.clip\(normalised"),
    ("the paper's Table 2 (`\"alpha\": 0.0807`)", r"\"alpha\": 0\.0807"),
    ("skipped doctests", r"doctest: \+SKIP"),
    ("citations of a DESIGN.md", r"DESIGN\.md"),
)
#: A measured number in prose: a percentage, a 4-decimal noise figure, seconds or minutes, a
#: before -> after pair.
MEASURED = r"\d ?%|\b0\.0\d{3}\b|\d(\.\d+)? ?(s|min)\b(?![a-z(])|\d(\.\d+)?%? -> \d"
#: part -> parts it must not import
FORBIDDEN = {"core": {"render", "nets", "refine", "benchmarks", "cli"},
             "render": {"nets", "refine", "cli"}, "nets": {"refine", "cli"},
             "refine": {"cli"}, "benchmarks": {"cli"}}


def sources(root: Path) -> list[Path]:
    return sorted(p for folder in FOLDERS for p in (root / folder).glob("*.py")
                  if p.name != Path(__file__).name)


def prose_lines(path: Path) -> list[str]:
    """The lines of the docstrings and comments of a module."""
    text = path.read_text(encoding="utf-8")
    out = []
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            out += doc.splitlines() if doc else []
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type == tokenize.COMMENT:
            out.append(tok.string)
    return out


def part_of_file(root: Path, path: Path) -> str:
    if path.parent.name == "ipm" and path.stem in ("cli", "__main__"):
        return "cli"
    return FOLDERS[path.parent.name]


def part_of_module(name: str) -> str | None:
    if name == "ipm.cli" or name == "ipm.__main__":
        return "cli"
    parts = name.split(".")
    if parts[0] != "ipm":
        return None
    if len(parts) > 1 and parts[1] in ("render", "nets", "refine", "benchmarks"):
        return parts[1]
    return "core"


def imports(path: Path) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            out.append(node.module)
            out += [f"{node.module}.{a.name}" for a in node.names if node.module == "ipm"]
    return out


def graph(root: Path) -> Counter:
    edges: Counter = Counter()
    for path in sources(root):
        src = part_of_file(root, path)
        for name in imports(path):
            dst = part_of_module(name)
            if dst and dst != src:
                edges[src, dst] += 1
    return edges


def counts(root: Path) -> list[tuple[str, int]]:
    lines = [line for p in sources(root) for line in p.read_text(encoding="utf-8").splitlines()]
    prose = [line for p in sources(root) for line in prose_lines(p)]
    return [(what, sum(bool(re.search(rx, line)) for line in lines)) for what, rx in PATTERNS] + [
        ("docstring and comment lines quoting a measured number",
         sum(bool(re.search(MEASURED, line)) for line in prose))]


def report(root: Path) -> str:
    rows = ["| repeated piece | lines |", "|---|---|"]
    rows += [f"| {what} | {n} |" for what, n in counts(root)]
    edges = graph(root)
    rows += ["", "| import | statements |", "|---|---|"]
    rows += [f"| {a} -> {b} | {n} |" for (a, b), n in sorted(edges.items())]
    bad = sorted(f"{a} -> {b}" for (a, b) in edges if b in FORBIDDEN.get(a, ()))
    rows += ["", "Forbidden arrows (core imports no part; render no nets/refine; nets no "
             "refine; no part imports the command line): " + (", ".join(bad) or "none") + "."]
    return "\n".join(rows) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1])
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    text = report(args.root)
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    print(text, end="")


if __name__ == "__main__":
    main()
