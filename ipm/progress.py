"""One look for the progress bars of ipm's long commands (rich, imported when a bar is made):
description, bar, done/total, the command's own fields, time elapsed and time left.  When
stderr is not a terminal (a log file, a pipe, a batch job) a bar would print nothing for
minutes: lines are printed there instead (:class:`LineProgress`)."""

from __future__ import annotations

import sys
import time
from types import SimpleNamespace


def progress_bar(*fields: str, transient: bool = False, console=None):
    """A ``rich.progress.Progress``; ``fields`` are extra text columns, e.g.
    ``"loss {task.fields[loss]:.4f}"``.  Without a terminal on stderr (and no ``console``
    given), a :class:`LineProgress` with the same methods."""
    if console is None and not sys.stderr.isatty():
        return LineProgress(*fields)
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                    *(TextColumn(f) for f in fields), TimeElapsedColumn(),
                    TimeRemainingColumn(), transient=transient, console=console)


class LineProgress:
    """A progress bar as lines on stderr, ``description done/total fields elapsed``: one per
    step of a task of at most :attr:`EVERY_STEP` steps (photos of a comparison), else at most
    one every :attr:`SECONDS` (renders of a fit), and the last step always."""

    EVERY_STEP = 100
    SECONDS = 10.0

    def __init__(self, *fields: str) -> None:
        self.fields = fields
        self.tasks: dict[int, dict] = {}

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, *exc) -> None:
        return None

    def add_task(self, description: str, total: float | None = None, completed: float = 0,
                 **fields) -> int:
        task = len(self.tasks)
        now = time.monotonic()
        self.tasks[task] = {"description": description, "total": total,
                            "completed": completed, "fields": fields, "start": now,
                            "said": now}
        return task

    def update(self, task: int, completed: float | None = None, advance: float | None = None,
               description: str | None = None, total: float | None = None, **fields) -> None:
        t = self.tasks[task]
        before = t["completed"]
        if completed is not None:
            t["completed"] = completed
        if advance is not None:
            t["completed"] += advance
        for key, value in (("description", description), ("total", total)):
            if value is not None:
                t[key] = value
        t["fields"].update(fields)
        now = time.monotonic()
        if t["completed"] == before:
            return
        few = t["total"] is not None and t["total"] <= self.EVERY_STEP
        if few or now - t["said"] >= self.SECONDS or t["completed"] == t["total"]:
            t["said"] = now
            shown = SimpleNamespace(fields=t["fields"])
            extra = " ".join(f.format(task=shown) for f in self.fields)
            total_text = f"/{t['total']:g}" if t["total"] is not None else ""
            print(f"{t['description']} {t['completed']:g}{total_text}"
                  + (f" {extra}" if extra else "") + f" ({now - t['start']:.0f} s)",
                  file=sys.stderr, flush=True)
