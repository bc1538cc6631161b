"""Fuzz the command-line tools: mutate sample inputs, run the real CLIs, classify what they do.

    python tools/fuzz.py --cases 1000 --jobs 2            # report in hrr_work/fuzz/report.{json,md}

Sample inputs are made first (a tiny model trained on the simulator-free dataset, a native npz, an
AMASS-style npz, a BVH, an out.h5) unless they are already in the work folder. Each case copies
one, applies one to three mutations chosen by a seeded random generator (so ``--seed`` and the case
number reproduce it) and runs one CLI on it in a fresh output folder, with a time limit and a memory
limit. Outcomes:

- ``clean error``: exit 2, one ``error:`` line, no traceback, nothing at the output path;
- ``ok``: exit 0 and an output that reads back finite and plausible (a garment near the body);
- failures: ``traceback`` (or any other exit status, a crash), ``hang`` (past the time limit),
  ``memory`` (killed, or MemoryError), ``bad output`` (exit 0 with a non-finite or absurd result),
  ``partial file`` (a failed run that left its output or a temporary file), and ``vague error``
  (a clean error whose line names neither the input nor the output, or that warnings precede).

Failing cases are kept under ``WORK/failures/`` with their command, for reproduction.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path

import numpy as np
from fuzz_cases import KINDS, make_case
from fuzz_door_files import unlock
from fuzz_samples import ROOT, Case, file_digest, make_samples
from tqdm import tqdm

FAILURES = ("traceback", "hang", "memory", "bad output", "partial file", "lost input", "vague error")


# ----------------------------------------------------------------------------- running and judging


def _limits(memory_gib: float):
    def apply():
        os.setsid()
        limit = int(memory_gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return apply


def run_case(case: Case, timeout: float, memory_gib: float) -> dict:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", **case.env}
    start = time.perf_counter()
    proc = subprocess.Popen(
        case.command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        stdin=subprocess.DEVNULL,
        preexec_fn=_limits(memory_gib),
        errors="replace",
    )
    err_parts: list[str] = []
    reader = threading.Thread(
        target=lambda: err_parts.extend(iter(lambda: proc.stderr.read(256), "")), daemon=True
    )
    reader.start()
    if case.interrupt is not None:  # once it works (its first progress bar), the signal, then the wait
        sig, delay = case.interrupt
        while proc.poll() is None and "|" not in "".join(err_parts) and time.perf_counter() - start < timeout:
            time.sleep(0.05)
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(sig)
    try:
        proc.wait(timeout=max(1.0, timeout - (time.perf_counter() - start)))
        hung = False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        hung = True
    reader.join(timeout=10)
    proc.stdout.close()
    err = "".join(err_parts)
    seconds = time.perf_counter() - start
    outcome, detail = judge(case, proc.returncode, err, hung)
    return {
        **asdict(case),
        "output": str(case.output),
        "command": case.command,
        "rc": proc.returncode,
        "seconds": round(seconds, 2),
        "outcome": outcome,
        "detail": detail,
        "stderr": err[-2000:],
    }


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:  # a name too long for the system: nothing can be there
        return False


def judge(case: Case, rc: int, err: str, hung: bool) -> tuple[str, str]:
    special = str(case.output).startswith(("/proc", "/sys", "/dev"))
    leftovers = (
        [p.name for p in case.output.parent.glob(f".{case.output.name[:40]}*")]
        if not special and _exists(case.output.parent)
        else []
    )
    if hung:
        return "hang", "past the time limit"
    changed = [
        Path(p).name
        for p, digest in case.keep.items()
        if not Path(p).exists() or file_digest(Path(p)) != digest
    ]
    if changed:
        return "lost input", f"changed or removed: {', '.join(changed)}"
    # interrupted (130, 143) or, in the instant after the command restored the default handlers, ended
    # by the signal itself: its output either complete or absent, no temporary file
    if (
        case.interrupt is not None
        and rc in (130, 143, -signal.SIGINT, -signal.SIGTERM)
        and "Traceback" not in err
    ):
        problem = check_output(case.output) if _exists(case.output) else ""
        if leftovers or problem:
            return "partial file", f"left {leftovers or problem} after the signal"
        return "clean error", err.strip().splitlines()[-1][-200:] if err.strip() else f"exit {rc}"
    if rc in (-9, 137) or "MemoryError" in err or "Cannot allocate memory" in err:
        return "memory", err.strip().splitlines()[-1] if err.strip() else "killed"
    if "Traceback" in err or "Segmentation fault" in err or rc not in (0, 2):
        last = err.strip().splitlines()[-1] if err.strip() else f"exit {rc}"
        return "traceback", last[-300:]
    if rc == 2:
        if leftovers or (
            not special
            and _exists(case.output)
            and case.kind not in ("output path", "output = input", "new output = input")
        ):
            return "partial file", f"left {leftovers or case.output.name}"
        lines = [ln for ln in err.splitlines() if "error:" in ln]
        if not lines:
            return "vague error", "exit 2 without an error line"
        if case.names and not any(n in lines[-1] for n in case.names) and "usage:" not in err:
            return "vague error", lines[-1][-300:]
        if "Warning" in err:  # warnings printed before the one line bury it
            return "vague error", "warnings before the error: " + next(
                ln for ln in err.splitlines() if "Warning" in ln
            )[-200:]
        return "clean error", lines[-1][-200:]
    if leftovers:
        return "partial file", f"left {leftovers}"
    if case.output.name == "none":  # a command that only prints (hrr-motion info, hrr-body info)
        return "ok", ""
    problem = check_output(case.output)
    return ("bad output", problem) if problem else ("ok", "")


def check_output(path: Path) -> str:
    """'' when a successful run's output reads back finite and plausible; else what is wrong."""
    if not _exists(path):
        return "exit 0 but no output"
    try:
        if path.suffix == ".h5":
            from hrr_garment.data.animation_file import read_animation_h5

            anim = read_animation_h5(path)
            if not (np.isfinite(anim.vertices).all() and np.isfinite(anim.joints).all()):
                return "non-finite vertices or joints"
            reach = np.linalg.norm(anim.vertices[:, :, None] - anim.joints[:, None], axis=-1).min(-1).max()
            return f"a garment vertex {reach:.2f} m from every joint" if reach > 1.5 else ""
        if (
            path.suffix == ".npy" and path.name == "api.npy"
        ):  # an API case: garment vertices relative to the pelvis
            rel = np.load(path, allow_pickle=False)
            if not np.isfinite(rel).all():
                return "non-finite vertices"
            return (
                f"a garment vertex {np.abs(rel).max():.3g} m from the pelvis"
                if np.abs(rel).max() > 2.5
                else ""
            )
        if path.suffix in (".npz", ".npy"):
            loaded = np.load(path, allow_pickle=False)
            arrays = [loaded] if isinstance(loaded, np.ndarray) else [loaded[k] for k in loaded.files]
            return "" if all(np.isfinite(a).all() for a in arrays) else "non-finite features"
        if path.suffix == ".glb":
            from hrr_garment.export.glb_read import read_glb_keyframes

            _, verts, _ = read_glb_keyframes(path)
            return "" if np.isfinite(verts).all() else "non-finite keyframes"
        if path.suffix == ".pc2":
            from hrr_garment.export.pointcache import read_pc2

            return "" if np.isfinite(read_pc2(path)[0]).all() else "non-finite points"
        if path.suffix == ".json":  # body.json and the like: strict JSON, no NaN or Infinity
            json.loads(path.read_text(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        if path.is_dir() and (path / "bundle.json").exists():
            from hrr_garment.artifacts.bundle_loader import load_bundle

            load_bundle(path)
        elif path.is_dir() and (path / "report.json").exists():
            json.loads(
                (path / "report.json").read_text(),
                parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)),
            )
        return "" if path.is_dir() or path.stat().st_size > 0 else "empty output"
    except Exception as exc:  # noqa: BLE001 - anything that fails to read back is a bad output
        return f"output does not read back: {type(exc).__name__}: {str(exc)[:200]}"


def _special_files(folder: str, names: list[str]) -> list[str]:
    """The names in ``folder`` that are neither files, folders nor links (pipes, sockets)."""
    paths = [Path(folder) / n for n in names]
    return [p.name for p in paths if not (p.is_symlink() or p.is_file() or p.is_dir())]


def write_report(results: list[dict], work: Path, seconds: float) -> str:
    kinds = sorted({r["kind"] for r in results})
    outcomes = ["clean error", "ok", *FAILURES]
    counts = Counter((r["kind"], r["outcome"]) for r in results)
    rows = ["| input kind | cases | " + " | ".join(outcomes) + " |", "|---|---:|" + "---:|" * len(outcomes)]
    for k in kinds:
        rows.append(
            f"| {k} | {sum(counts[k, o] for o in outcomes)} | "
            + " | ".join(str(counts[k, o]) for o in outcomes)
            + " |"
        )
    total = Counter(r["outcome"] for r in results)
    rows.append(f"| all | {len(results)} | " + " | ".join(str(total[o]) for o in outcomes) + " |")
    failures = [r for r in results if r["outcome"] in FAILURES]
    lines = [f"{len(results)} cases in {seconds / 60:.1f} min; failures: {len(failures)}", "", *rows]
    if failures:
        lines += ["", "Failures:"] + [
            f"- #{r['number']} {r['kind']} ({r['mutation']}): {r['outcome']}: {r['detail']}" for r in failures
        ]
    text = "\n".join(lines) + "\n"
    (work / "report.md").write_text(text)
    (work / "report.json").write_text(json.dumps({"seconds": seconds, "results": results}, indent=1))
    return text


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--cases", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    p.add_argument("--timeout", type=float, default=60.0, help="seconds before a run counts as a hang")
    p.add_argument("--memory-gib", type=float, default=8.0, help="address-space limit per run")
    p.add_argument("--only", choices=list(KINDS), default=None, help="one input kind")
    p.add_argument("--work", type=Path, default=ROOT / "hrr_work" / "fuzz")
    args = p.parse_args(argv)
    args.work = args.work.resolve()  # a relative folder would make the cases' links dangle
    samples = make_samples(args.work / "samples")
    shutil.rmtree(args.work / "failures", ignore_errors=True)

    def one(n: int) -> dict:
        """Make case ``n`` (its own seeded generator: reproducible alone) and run it."""
        rng = np.random.default_rng([args.seed, n])
        folder = args.work / "cases" / f"{n:05d}"
        case = None
        try:
            case = make_case(n, samples, args.work, rng)
            while args.only and case.kind != args.only:
                # a case of another kind drawn first may have made files here (a locked folder): gone
                unlock(folder)
                shutil.rmtree(folder, ignore_errors=True)
                case = make_case(n, samples, args.work, rng)
            r = run_case(case, args.timeout, args.memory_gib)
        except Exception as exc:  # noqa: BLE001 - a fuzzer bug must not hide the other cases; it counts as a failure
            r = {
                "number": n,
                "kind": case.kind if case else "fuzzer",
                "mutation": case.mutation if case else "",
                "command": case.command if case else [],
                "output": str(case.output) if case else "",
                "rc": None,
                "seconds": 0.0,
                "outcome": "traceback",
                "detail": f"fuzzer error: {type(exc).__name__}: {exc}",
                "stderr": "",
            }
        unlock(folder)
        if r["outcome"] in FAILURES:
            kept = args.work / "failures" / folder.name
            # links kept as links and pipes left out: a copy through a link to /dev/zero never ends
            shutil.copytree(folder, kept, symlinks=True, ignore=_special_files, dirs_exist_ok=True)
            (kept / "command.txt").write_text(" ".join(map(str, r["command"])) + "\n\n" + r["stderr"])
        shutil.rmtree(folder, ignore_errors=True)
        return r

    start = time.perf_counter()
    with ThreadPoolExecutor(args.jobs) as pool:
        futures = [pool.submit(one, n) for n in range(args.cases)]
        results = [
            f.result() for f in tqdm(as_completed(futures), total=len(futures), desc="fuzz", unit="case")
        ]
    results.sort(key=lambda r: r["number"])
    print(write_report(results, args.work, time.perf_counter() - start))
    return 1 if any(r["outcome"] in FAILURES for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
