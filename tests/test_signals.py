"""Interrupts, workers and outputs: Ctrl-C and SIGTERM stop a run in one line, workers die with pkmtol,
and a run's files are never half-written or clobbered (issue 25).

The signal tests start ``python -m pkmtol.cli`` as a child process, wait until it is computing
(its workers, when asked for, are alive), send the signal, and check the exit code, the one-line
message, the output folder (no files, or the previous run whole) and that no worker survives 5 s.
Worker processes are found through ``/proc`` (their parent pid), without psutil.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pkmtol.cli import main
from pkmtol.exceptions import OutputError, OutputLockedError
from pkmtol.present.run_folder import MANIFEST, RunFolder

ROOT = Path(__file__).resolve().parents[1]
SEED = ROOT / "robots" / "r2rps_ups"
SMALL = ["--samples", "300", "--exact-samples", "0", "--verification-poses", "30", "--no-progress"]
LINUX = Path("/proc/self/stat").exists()

# long enough to be interrupted mid-computation (seconds of work), small enough to start fast
LONG = {
    "allocate": [
        "allocate",
        str(SEED),
        "--samples",
        "200000",
        "--verification-poses",
        "3000",
        "--no-progress",
    ],
    "calibrate": [
        "calibrate",
        str(SEED),
        "--simulate",
        "--machines",
        "2000",
        "--random-sets",
        "0",
        "--candidates",
        "20",
        "--holdout",
        "20",
    ],
    "sweep": ["sweep", str(SEED), "--vary", "reference_point.position_m[2]=0.2:0.4:40", "--no-progress"],
}


def _children(pid: int) -> list[int]:
    """Pids of the processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[1]) == pid:
            out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"  # a zombie has exited


def _start(argv: list[str], out: Path) -> subprocess.Popen:
    argv = [*argv, "--no-progress"] if argv[0] == "allocate" else argv
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PYTHONUNBUFFERED="1")
    return subprocess.Popen(
        [sys.executable, "-m", "pkmtol.cli", *argv, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        cwd=str(out.parent),
    )


def _wait_until_computing(proc: subprocess.Popen, workers: int, timeout: float = 90.0) -> list[int]:
    """Wait until ``proc`` has started its ``workers`` (or, serial, has run a few seconds)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        assert proc.poll() is None, proc.communicate()
        kids = _children(proc.pid)
        if workers > 1 and len(kids) >= workers:
            time.sleep(0.5)
            return _children(proc.pid)
        if workers == 1 and time.monotonic() - t0 > 4.0:
            return kids
        time.sleep(0.2)
    raise AssertionError("the run did not start its workers in time")


@pytest.mark.skipif(not LINUX, reason="needs /proc")
@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("command", sorted(LONG))
def test_a_signal_stops_the_run_in_one_line_and_writes_nothing(tmp_path, command, sig, workers):
    out = tmp_path / "out"
    argv = LONG[command] + (["--workers", "2"] if workers > 1 else [])
    proc = _start(argv, out)
    kids = _wait_until_computing(proc, workers)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    text = stderr.decode()
    assert proc.returncode == 128 + int(sig), text
    assert text.strip().splitlines()[-1] == "pkmtol: interrupted; nothing was written", text
    assert "Traceback" not in text, text
    assert not any(p.is_file() for p in out.rglob("*")) if out.exists() else True
    deadline = time.monotonic() + 5.0
    while any(_alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [k for k in kids if _alive(k)], "a worker outlived pkmtol"


@pytest.mark.skipif(not LINUX, reason="needs /proc")
def test_workers_die_when_pkmtol_is_killed(tmp_path):
    out = tmp_path / "out"
    proc = _start(LONG["calibrate"] + ["--workers", "2"], out)
    kids = _wait_until_computing(proc, 2)
    proc.send_signal(signal.SIGKILL)  # no handler runs: the workers must notice on their own
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 5.0
    while any(_alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert kids and not [k for k in kids if _alive(k)], "a worker outlived a killed pkmtol"


def test_the_worker_initializer_arms_the_parent_death_signal():
    """In-process check of the mechanism: a forked worker exits when its parent pid changes."""
    from pkmtol import executor

    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child plays a worker whose parent is a pid that is not its parent
        os.close(r)
        try:
            executor._worker_init(os.getppid() + 10**6)  # "the parent is already gone": exits
        finally:
            os.write(w, b"survived")
            os._exit(0)
    os.close(w)
    _, status = os.waitpid(pid, 0)
    said = os.read(r, 100)
    os.close(r)
    assert said == b"" and os.WEXITSTATUS(status) == 1


# --- outputs: never clobbered, never half-written -------------------------------------------------


def test_html_at_a_file_of_the_same_run_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    code = main(["allocate", str(SEED), "--out", str(out), "--html", str(out / "allocation.json"), *SMALL])
    err = capsys.readouterr().err
    assert code == 2 and "of the same run" in err, err
    assert not (out / "allocation.json").exists()


def test_calibrate_plan_at_a_file_of_the_run_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    code = main(["calibrate", str(SEED), "--out", str(out), "--plan", str(out / "calibration_plan.json")])
    assert code == 2 and "of the same run" in capsys.readouterr().err


def test_special_files_are_refused_and_symlinks_written_through(tmp_path, capsys):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert main(["errors", str(SEED), "--json", str(fifo)]) == 2
    assert "not a regular file" in capsys.readouterr().err
    assert fifo.is_fifo()
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    assert main(["errors", str(SEED), "--json", str(link)]) == 0
    assert link.is_symlink() and json.loads(real.read_text())


def test_allocate_leaves_a_users_file_no_manifest_lists(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "tolerances.pdf").write_bytes(b"%PDF my own")
    assert main(["allocate", str(SEED), "--out", str(out), "--no-figures", *SMALL]) == 0
    assert (out / "tolerances.pdf").read_bytes() == b"%PDF my own"


def test_calibrate_takes_the_run_folder_lock_and_replaces_the_previous_run(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "study.md").write_text("a study of an earlier run")
    (out / MANIFEST).write_text(json.dumps({"pkmtol_run": 1, "files": ["study.md"], "outside": []}))
    with RunFolder(out), pytest.raises(OutputLockedError):
        from pkmtol.cli import run

        run(["calibrate", str(SEED), "--out", str(out), "--random-sets", "0", "--no-figures"])
    assert main(["calibrate", str(SEED), "--out", str(out), "--random-sets", "0", "--no-figures"]) == 0
    listed = json.loads((out / MANIFEST).read_text())["files"]
    assert sorted(listed) == ["calibration_plan.json", "calibration_plan.md"]
    assert not (out / "study.md").exists()  # the earlier run's file, listed by its manifest


def test_sweep_writes_a_run_folder(tmp_path):
    out = tmp_path / "out"
    argv = ["sweep", str(SEED), "--vary", "reference_point.position_m[2]=0.25:0.3:2", "--no-figures"]
    assert main([*argv, "--no-progress", "--out", str(out)]) == 0
    assert sorted(json.loads((out / MANIFEST).read_text())["files"]) == ["sweep.csv", "sweep.json"]


def test_a_special_file_is_refused_by_the_writer_itself(tmp_path):
    from pkmtol.files import write_atomic

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(OutputError, match="not a regular file"):
        write_atomic(fifo, b"x")
    with pytest.raises(OutputError, match="a folder"):
        write_atomic(tmp_path, b"x")


# --- a Dask address that accepts but does not answer ----------------------------------------------


def _server(greeting: bytes | None):
    import socket
    import threading

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(4)
    held = []

    def serve() -> None:
        while True:
            try:
                conn, _ = sock.accept()
            except OSError:
                return
            held.append(conn)
            if greeting is not None:
                conn.sendall(greeting)

    threading.Thread(target=serve, daemon=True).start()
    return sock, f"tcp://127.0.0.1:{sock.getsockname()[1]}"


@pytest.mark.parametrize(
    ("greeting", "says"),
    [(None, "sent no Dask handshake within 1 s"), (b"SSH-2.0-OpenSSH_9.0\r\n", "is not a Dask scheduler")],
)
def test_a_silent_or_foreign_server_is_not_taken_for_a_scheduler(monkeypatch, greeting, says):
    from pkmtol import executor
    from pkmtol.exceptions import ExecutorError

    monkeypatch.setattr(executor, "DASK_TIMEOUT_S", 1.0)
    sock, address = _server(greeting)
    t0 = time.monotonic()
    try:
        with pytest.raises(ExecutorError, match=says):
            executor._probe(address)
    finally:
        sock.close()
    assert time.monotonic() - t0 < 3.0


@pytest.mark.skipif(not LINUX, reason="needs /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_dask_local_workers_do_not_outlive_pkmtol(tmp_path, sig):
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    proc = _start(LONG["calibrate"] + ["--dask", "local", "--workers", "2"], out)
    kids = _wait_until_computing(proc, 2, timeout=120)
    time.sleep(3.0)  # the cluster's workers are up and working
    kids = sorted(set(kids) | set(_children(proc.pid)))
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=60)
    if sig == signal.SIGTERM:
        assert proc.returncode == 143
        assert stderr.decode().strip().splitlines()[-1] == "pkmtol: interrupted; nothing was written"
    deadline = time.monotonic() + 5.0
    while any(_alive(k) for k in kids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert kids and not [k for k in kids if _alive(k)], "a Dask worker outlived pkmtol"


@pytest.mark.skipif(not LINUX, reason="needs /proc")
def test_ctrl_c_during_new_leaves_no_folder(tmp_path):
    out = tmp_path / "robot"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.Popen(
        [sys.executable, "-m", "pkmtol.cli", "new", "tricept", "--out", str(out), "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    t0 = time.monotonic()
    while not any(p.name.startswith(".robot.") for p in tmp_path.iterdir()):  # it is writing the draft
        assert proc.poll() is None and time.monotonic() - t0 < 60, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr.decode()
    assert stderr.decode().strip().splitlines()[-1] == "pkmtol: interrupted; nothing was written"
    assert list(tmp_path.iterdir()) == []  # neither the robot nor its temporary folder
