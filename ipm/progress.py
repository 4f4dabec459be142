"""One look for the progress bars of ipm's long commands (rich, imported when a bar is made):
description, bar, done/total, the command's own fields, time elapsed and time left."""

from __future__ import annotations


def progress_bar(*fields: str, transient: bool = False, console=None):
    """A ``rich.progress.Progress``; ``fields`` are extra text columns, e.g.
    ``"loss {task.fields[loss]:.4f}"``."""
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
