"""``ipm fit FOLDER`` at scale: photos per minute with one worker and with two, as local
processes and as local Ray actors, each worker's peak memory, and whether every photo's
``params.json`` is the same whichever way it ran; a Ray cluster of two nodes on this machine
(``ray start --head`` and a second ``ray start --address``, one CPU each) fitting the folder
over both; and a run killed (SIGKILL of the driver) and resumed on the photos plus three bad
files, against the same run uninterrupted.

    python -m ipm.benchmarks.batch_fit --photos ../shared/real-yarns --pixel-size 0.0021 \\
        --setup backlit --work /tmp/batch --out benchmarks/results/batch_fit.md

Each run is one fresh ``ipm fit FOLDER -o OUT`` process, timed from its start to its exit
(Ray's start included); the fits are ``ipm fit``'s default (the nets' reading, no search)
unless ``--refine``.  Memory: each worker process's peak resident set (VmHWM), polled while
it runs; the workers are the processes named in the photos' ``run.json``.  The work folder
keeps every run's output (the report figure of the one-worker run is the guide's figure).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path

from ipm.benchmarks.machine import markdown_header, publish
from ipm.benchmarks.startup import DEFAULT_IPM
from ipm.dataset import photo_files

#: The bad files of the resume run: (name, bytes).
BAD_FILES = (("bad_text.png", b"this is not an image\n"),
             ("bad_empty.jpg", b""),
             ("bad_truncated.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00"))


class PeakMemory:
    """Every process's peak resident set (VmHWM, MB) and CPU time (user + system, s) seen
    while polling all of them."""

    def __init__(self, every: float = 0.5) -> None:
        self.peak: dict[int, float] = {}
        self.cpu: dict[int, float] = {}
        self._tick = os.sysconf("SC_CLK_TCK")
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, args=(every,), daemon=True)

    def _poll(self, every: float) -> None:
        while not self._stop.is_set():
            for pid in (int(p) for p in os.listdir("/proc") if p.isdigit()):
                try:
                    with open(f"/proc/{pid}/status", encoding="ascii", errors="replace") as f:
                        for line in f:
                            if line.startswith("VmHWM:"):
                                mb = int(line.split()[1]) / 1024
                                self.peak[pid] = max(self.peak.get(pid, 0.0), mb)
                                break
                    with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
                        fields = f.read().rsplit(")", 1)[1].split()
                    self.cpu[pid] = (int(fields[11]) + int(fields[12])) / self._tick
                except (OSError, IndexError, ValueError):
                    continue
            self._stop.wait(every)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def fit_command(photos: Path, out: Path, args, *extra: str) -> list[str]:
    return [DEFAULT_IPM, "fit", str(photos), "-o", str(out), "--pixel-size",
            str(args.pixel_size), "--setup", args.setup,
            *(["--refine"] if args.refine else []), *extra]


def timed(cmd: list[str], log: Path, env: dict | None = None) -> tuple[float, int, PeakMemory]:
    with PeakMemory() as mem, open(log, "w") as f:
        t0 = time.perf_counter()
        rc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=env).returncode
        seconds = time.perf_counter() - t0
    return seconds, rc, mem


def outputs(out: Path) -> dict[str, bytes]:
    """Every photo's params.json in ``out``, by folder."""
    return {p.parent.name: p.read_bytes() for p in sorted(out.glob("*/params.json"))}


def runs_of(out: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted(out.glob("*/run.json"))]


def worker_peaks(out: Path, mem: PeakMemory) -> tuple[list[float], float]:
    """The workers' peak memory (MB) and their CPU time together (s, as last polled)."""
    pids = {r["worker"]["pid"] for r in runs_of(out)}
    return (sorted(mem.peak.get(pid, float("nan")) for pid in pids),
            sum(mem.cpu.get(pid, 0.0) for pid in pids))


def throughput(args, photos: Path) -> tuple[list[str], dict[str, bytes], Path]:
    """The four ways side by side; returns the table's lines, the one-worker run's
    params.json files and its folder."""
    count = len(photo_files(photos))
    ways = [("local, 1 worker (this process)", []), ("local, 2 workers", ["--workers", "2"]),
            ("Ray local, 1 actor", ["--ray", "local", "--workers", "1"]),
            ("Ray local, 2 actors", ["--ray", "local", "--workers", "2"])]
    lines = ["| how | wall time (s) | photos per minute | vs. one worker | cores busy (workers' "
             "CPU time / wall time) | worker peak memory (MB) | params.json as one worker's |",
             "|---|---|---|---|---|---|---|"]
    reference, first = None, None
    rate1 = {}
    for k, (name, extra) in enumerate(ways):
        out = args.work / f"run{k}"
        shutil.rmtree(out, ignore_errors=True)
        seconds, rc, mem = timed(fit_command(photos, out, args, *extra), args.work / f"run{k}.log")
        if rc:
            raise SystemExit(f"{name}: exit {rc}; see {args.work}/run{k}.log")
        files = outputs(out)
        if len(files) != count:
            raise SystemExit(f"{name}: {len(files)} of {count} photos fitted")
        if reference is None:
            reference, first = files, out
        same = sum(files[k2] == reference[k2] for k2 in reference)
        rate = 60 * count / seconds
        base = rate1.setdefault(name.split(",")[0], rate)
        peaks, cpu = worker_peaks(out, mem)
        lines.append(f"| {name} | {seconds:.0f} | {rate:.2f} | {rate / base:.2f}x | "
                     f"{cpu / seconds:.2f} | {', '.join(f'{p:.0f}' for p in peaks)} | "
                     f"{same} of {count} |")
        print(lines[-1], flush=True)
    return lines, reference, first


def two_nodes(args, photos: Path, reference: dict[str, bytes]) -> list[str]:
    """A Ray cluster of two nodes on this machine, one CPU each, fitting the folder."""
    port = "6391"
    env = dict(os.environ, RAY_AUTH_MODE="token")  # `ray start` makes a token; all use it
    subprocess.run(["ray", "stop", "--force"], capture_output=True, env=env)
    try:
        for cmd in (["ray", "start", "--head", "--port", port, "--num-cpus", "1",
                     "--include-dashboard", "false"],
                    ["ray", "start", "--address", f"127.0.0.1:{port}", "--num-cpus", "1"]):
            r = subprocess.run(cmd, capture_output=True, text=True, env=env)
            if r.returncode:
                raise SystemExit(f"{' '.join(cmd)} failed:\n{r.stdout}\n{r.stderr}")
        out = args.work / "cluster"
        shutil.rmtree(out, ignore_errors=True)
        seconds, rc, _ = timed(fit_command(photos, out, args, "--ray", f"127.0.0.1:{port}"),
                               args.work / "cluster.log", env)
    finally:
        subprocess.run(["ray", "stop", "--force"], capture_output=True, env=env)
    if rc:
        raise SystemExit(f"the two-node run: exit {rc}; see {args.work}/cluster.log")
    files = outputs(out)
    nodes: dict[str, int] = {}
    for r in runs_of(out):
        node = r["worker"].get("node", "?")
        nodes[node] = nodes.get(node, 0) + 1
    same = sum(files.get(k) == v for k, v in reference.items())
    return [f"Two Ray nodes on this machine (`ray start --head --port {port} --num-cpus 1`, "
            f"then `ray start --address 127.0.0.1:{port} --num-cpus 1`), `ipm fit "
            f"{photos.name} --ray 127.0.0.1:{port}`: {len(files)} photos in {seconds:.0f} s, "
            f"fitted by {len(nodes)} nodes (" + ", ".join(
                f"node {n}: {c} photos" for n, c in sorted(nodes.items())) +
            f"); params.json as one worker's: **{same} of {len(reference)}**."]


def resume(args, photos: Path) -> list[str]:
    """20 good photos and 3 bad files: a run killed mid-way and resumed, against the same
    run uninterrupted."""
    folder = args.work / "mixed"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    good = photo_files(photos)[:20]
    for p in good:
        shutil.copy(p, folder / p.name)
    for name, data in BAD_FILES:
        (folder / name).write_bytes(data)
    whole = args.work / "mixed-whole"
    shutil.rmtree(whole, ignore_errors=True)
    _, rc_whole, _ = timed(fit_command(folder, whole, args, "--workers", "2"),
                           args.work / "mixed-whole.log")
    killed = args.work / "mixed-killed"
    shutil.rmtree(killed, ignore_errors=True)
    log = open(args.work / "mixed-killed-1.log", "w")
    proc = subprocess.Popen(fit_command(folder, killed, args, "--workers", "2"), stdout=log,
                            stderr=subprocess.STDOUT)
    while len(outputs(killed)) < len(good) // 3 and proc.poll() is None:
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    log.close()
    time.sleep(2)  # the workers follow their parent (parent-death signal)
    before = {p.parent.name: (p.stat().st_mtime_ns, p.stat().st_ino)
              for p in killed.glob("*/params.json")}
    seconds, rc, _ = timed(fit_command(folder, killed, args, "--workers", "2"),
                           args.work / "mixed-killed-2.log")
    after = {p.parent.name: (p.stat().st_mtime_ns, p.stat().st_ino)
             for p in killed.glob("*/params.json")}
    kept = sum(after.get(k) == v for k, v in before.items())
    refitted = len(before) - kept
    errors = [line for line in (args.work / "mixed-killed-2.log").read_text().splitlines()
              if line.startswith("error: not fitted")]
    same = {name: (killed / name).read_bytes() == (whole / name).read_bytes()
            for name in ("fits.csv", "report.md", "report.png")}
    params_same = outputs(killed) == outputs(whole)
    return [f"{len(good)} photos and {len(BAD_FILES)} bad files (text named .png, an empty "
            ".jpg, a PNG cut after its header), `--workers 2`: the driver killed (SIGKILL) "
            f"once {len(before)} photos were written, then the same command run again.", "",
            "| check | result |", "|---|---|",
            f"| photos fitted before the kill, left as they were by the resume | {kept} of "
            f"{len(before)} ({refitted} fitted twice) |",
            f"| photos fitted after the resume | {len(after)} of {len(good)} |",
            f"| one-line reasons for the bad files | {len(errors)}: " + "; ".join(
                f"`{e.removeprefix('error: not fitted: ')}`" for e in errors) + " |",
            f"| exit status, resumed / uninterrupted | {rc} / {rc_whole} |",
            "| fits.csv, report.md, report.png as the uninterrupted run's | " + ", ".join(
                f"{k}: {'same' if v else 'DIFFERENT'}" for k, v in same.items()) + " |",
            f"| every params.json as the uninterrupted run's | {params_same} |",
            f"| the resume's wall time | {seconds:.0f} s |"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--photos", type=Path, required=True)
    ap.add_argument("--pixel-size", type=float, required=True)
    ap.add_argument("--setup", default="backlit")
    ap.add_argument("--refine", action="store_true", help="fit with the search")
    ap.add_argument("--work", type=Path, required=True, help="folder for the runs")
    ap.add_argument("--parts", default="throughput,cluster,resume")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    parts = args.parts.split(",")
    count = len(photo_files(args.photos))
    command = (f"python -m ipm.benchmarks.batch_fit --photos {args.photos} --pixel-size "
               f"{args.pixel_size:g} --setup {args.setup}" + (" --refine" if args.refine else "")
               + f" --work {args.work}" + (f" --parts {args.parts}"
                                           if args.parts != ap.get_default("parts") else "")
               + (f" --out {args.out}" if args.out else ""))
    lines = [markdown_header("ipm fit FOLDER: throughput, workers, Ray, resume", command,
                             "ray", "torch", "mitsuba"),
             f"{count} photos of `{args.photos}` at {args.pixel_size:g} mm per pixel, "
             f"{args.setup}, fitted as `ipm fit` does by default" +
             (" with the search (`--refine`)" if args.refine else " (the nets' reading, the "
              "renders shown in the photo's capture, the textile block; no search)") + ".", ""]
    reference = None
    if "throughput" in parts:
        table, reference, first = throughput(args, args.photos)
        lines += ["## Throughput", ""] + table + [""]
    if "cluster" in parts:
        if reference is None:  # the one-worker run of an earlier call
            reference = outputs(args.work / "run0")
            if not reference:
                raise SystemExit(f"--parts cluster needs {args.work}/run0: run throughput")
        lines += ["## Two nodes", ""] + two_nodes(args, args.photos, reference) + [""]
    if "resume" in parts:
        lines += ["## Killed and resumed", ""] + resume(args, args.photos) + [""]
    publish("\n".join(lines), args.out)


if __name__ == "__main__":
    main()
