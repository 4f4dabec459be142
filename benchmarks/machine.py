"""Machine metadata printed with every benchmark: numbers mean little without it."""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path


def git_commit() -> str:
    """The checked-out commit, marked if tracked code (``*.py``, ``*.sh``) differs from it:
    a report made from changes not yet committed says so."""
    here = Path(__file__).resolve().parent  # the code's checkout, wherever the data lies
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True, cwd=here).stdout.strip()
        changed = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", "*.py", "*.sh"],
                                 capture_output=True, cwd=here).returncode != 0
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return f"{head} with uncommitted code changes" if changed else head


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def versions(*packages: str) -> dict[str, str]:
    out = {}
    for p in packages:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            out[p] = "-"
    return out


def machine_info(*packages: str) -> dict:
    return {"cpu": cpu_model(), "cores": os.cpu_count(), "python": platform.python_version(),
            "commit": git_commit(), **versions("numpy", *packages)}


def markdown_header(title: str, command: str, *packages: str) -> str:
    info = machine_info(*packages)
    lines = [f"# {title}", "", f"Made by `{command}`.", ""]
    lines += [f"- {k}: {v}" for k, v in info.items()]
    return "\n".join(lines) + "\n"


def publish(text: str, out: str | None, data=None) -> None:
    """Print a report and, with ``out``, write it there (atomically), and ``data`` (JSON-ready)
    beside it as ``<out stem>.json``."""
    import json

    from ipm.io import write_text

    if out:
        write_text(out, text)
        if data is not None:
            write_text(out.rsplit(".", 1)[0] + ".json", json.dumps(data, indent=1))
    print(text)
