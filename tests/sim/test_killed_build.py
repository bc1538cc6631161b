"""A build killed with SIGKILL or SIGTERM leaves no process behind and resumes (issue 48, reproducer
12): its pool workers die with it (:mod:`hrr_garment.workers`), and a re-run finishes the parts."""

import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from hrr_garment.data.dataset import GarmentDataset


def session_processes(sid: int) -> list[str]:
    """The processes of session ``sid`` still alive (zombies are dead: their parent reaps them)."""
    out = subprocess.run(
        ["ps", "-s", str(sid), "-o", "pid=,stat=,args="], capture_output=True, text=True
    ).stdout
    return [line for line in out.splitlines() if line.split()[1:2] != ["Z"]]


def workers_asked_to_die(sid: int, count: int) -> bool:
    """Whether ``count`` pool workers of session ``sid`` have run :func:`die_with_parent`: it sets
    their SIGINT to ignored, which ``/proc/<pid>/status`` shows (a worker still importing the
    simulator has not, and would outlive a parent killed then until its import ends)."""
    ready = 0
    for line in session_processes(sid):
        pid, _stat, args = line.split(maxsplit=2)
        if "multiprocessing.spawn" not in args:
            continue
        try:
            status = Path(f"/proc/{pid}/status").read_text()
        except OSError:  # it ended meanwhile
            continue
        ignored = int(next(f.split()[1] for f in status.splitlines() if f.startswith("SigIgn:")), 16)
        ready += bool(ignored & (1 << (signal.SIGINT - 1)))
    return ready >= count


def started_alone(cmd: list[str]) -> subprocess.Popen:
    """``cmd`` started in a session of its own (its process id the session's), its output dropped,
    with SIGINT at its default (and so in its workers until die_with_parent ignores it): a runner
    started in the background of a shell without job control (nohup, a CI script) ignores it, every
    child inherited that, and the workers read as ready while still importing the simulator,
    outliving the killed run by the rest of their import (past 5 s on a loaded 2-core machine)."""
    return subprocess.Popen(
        cmd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def wait_for(condition, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.2)
    return condition()


@pytest.mark.slow  # a process pool started, killed and waited for: 3 to 6 s
def test_workers_of_a_killed_pool_die_with_it(tmp_path):
    """The mechanism on its own: a process pool whose workers called die_with_parent, its parent
    SIGKILLed mid-task, leaves nothing within 5 s (without it the workers sleep on)."""
    script = tmp_path / "parent.py"
    script.write_text(
        textwrap.dedent("""
        import multiprocessing as mp, os, time
        from concurrent.futures import ProcessPoolExecutor
        from hrr_garment.workers import die_with_parent
        if __name__ == "__main__":
            ctx = mp.get_context("spawn")
            with ProcessPoolExecutor(
                2, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),)
            ) as pool:
                futures = [pool.submit(time.sleep, 600) for _ in range(2)]
                print("started", flush=True)
                time.sleep(600)
    """)
    )
    parent = subprocess.Popen(
        [sys.executable, str(script)], stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        assert parent.stdout.readline().strip() == "started"
        assert wait_for(lambda: len(session_processes(parent.pid)) >= 3, 30)  # the parent and its two workers
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        assert wait_for(lambda: not session_processes(parent.pid), 5), session_processes(parent.pid)
    finally:
        subprocess.run(["pkill", "-9", "-s", str(parent.pid)])


@pytest.mark.sim
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_a_killed_build_leaves_no_process_and_resumes(tmp_path, sig):
    """SIGKILL: the workers die with the build. SIGTERM: the build stops its workers and exits 143
    at once (not when their sequences finish). Either way a re-run resumes."""
    out = tmp_path / "skirt.h5"
    cmd = [
        sys.executable,
        "-m",
        "hrr_garment.cli.simulate",
        "--garment",
        "skirt",
        "--preset",
        "tiny",
        "--jobs",
        "2",
        "--motions",
        "walk",
        "spin",
        "--seconds",
        "2",
        "--no-preview",
        "-o",
        str(out),
    ]
    build = started_alone(cmd)
    try:
        # two workers started and asked to die with the build, a sequence each under way
        assert wait_for(lambda: workers_asked_to_die(build.pid, 2), 120), session_processes(build.pid)
        time.sleep(2.0)
        build.send_signal(sig)
        assert build.wait(timeout=10) == (-9 if sig == signal.SIGKILL else 143)
        assert wait_for(lambda: not session_processes(build.pid), 5), session_processes(build.pid)
    finally:
        subprocess.run(["pkill", "-9", "-s", str(build.pid)])
    assert not out.exists()
    rerun = subprocess.run(cmd, capture_output=True, text=True)
    assert rerun.returncode == 0, rerun.stderr[-2000:]
    assert len(GarmentDataset(out)) == 2
