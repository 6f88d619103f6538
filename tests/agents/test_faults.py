"""Faults of the file system (no space left, a file too large, permission denied, a read-only
folder, a network file system gone) end every command in one line that names the path and the
cause, exit status 74; the files written before stay whole and ``run.json`` says ``failed``
where it can still be written.

Most faults are injected into the write path in process (``os.fsync``, ``tempfile.mkstemp``,
SB3's monitor writer raising the ``OSError`` the kernel gives): the tests may run as root, whom
permissions do not stop, and need no small file system. A file-size limit (``ulimit -f``) is
real, in a subprocess; so is ``chmod`` of the run folder when not root.
"""

from __future__ import annotations

import errno
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from tiny_budgets import TINY_SET
from training_processes import ROOT, start_training, wait_for_recorded_checkpoint

from agents import evaluate, main_job, run_folder, train_cli
from agents.rollout import make_vec
from rigid_env import cli
from rigid_env.bench import __main__ as bench_cli
from rigid_env.files import TEMP_SUFFIX, WriteError, atomic_open, write_text

ID = "RigidEnv/Reorient-v0"
TRAIN = ["--timesteps", "256", "--n-envs", "2", "--checkpoint-every", "64", "--no-progress",
         *TINY_SET]  # fmt: skip
KEPT = "files written before are kept"


def fault(code: int) -> OSError:
    return OSError(code, os.strerror(code))


def one_fault_line(capsys, main, prog, argv) -> str:
    """Run a command that meets a fault: exit 74, one line on stderr (returned)."""
    capsys.readouterr()
    code = cli.run(main, prog, argv)
    err = capsys.readouterr().err
    assert code == cli.EXIT_FAULT, err
    assert err.startswith(f"{prog}: error: ") and err.count("\n") == 1, err
    assert err.rstrip().endswith(KEPT), err
    return err


def fail_fsync_of(monkeypatch, name: str, code: int, after: int = 0) -> None:
    """``os.fsync`` of a temporary file of ``name`` fails with ``code`` from its ``after``-th
    call on (as a full disk reports a write it could not place)."""
    real, calls = os.fsync, [0]

    def fsync(fd: int) -> None:
        if Path(os.readlink(f"/proc/self/fd/{fd}")).name.startswith(f".{name}."):
            calls[0] += 1
            if calls[0] > after:
                raise fault(code)
        real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def no_partials(folder: Path) -> bool:
    return not list(folder.rglob(f"*{TEMP_SUFFIX}"))


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EDQUOT, errno.EIO])
def test_a_full_disk_at_a_checkpoint_fails_the_run_in_one_line(tmp_path, capsys, monkeypatch, code):
    run = tmp_path / "run"
    fail_fsync_of(monkeypatch, "checkpoint.zip", code, after=1)  # the second checkpoint
    err = one_fault_line(capsys, train_cli.main, train_cli.PROG, [*TRAIN, "--out", str(run)])
    name = errno.errorcode[code]
    assert f": error: {run / 'checkpoint.zip'}: {os.strerror(code)} ({name});" in err
    record = run_folder.read(run)
    assert record["status"] == "failed" and record["checkpoint"]["steps"] == 64
    model, _ = run_folder.load_model(run / "checkpoint.zip", "checkpoint")  # the first: whole
    assert model.num_timesteps == 64 and no_partials(run)
    if code != errno.ENOSPC:
        return
    # The failed run resumes from that checkpoint once there is room again.
    monkeypatch.undo()
    assert cli.run(train_cli.main, train_cli.PROG, ["--resume", str(run), "--no-progress"]) == 0
    assert run_folder.read(run)["status"] == "finished"


def test_a_network_file_system_gone_under_the_monitor_log_names_the_run_folder(
    tmp_path, capsys, monkeypatch
):
    """SB3's monitor writes ``monitor.csv`` itself (no file name in its error): the message
    names the run folder."""
    from stable_baselines3.common.monitor import ResultsWriter

    def write_row(self, row):
        raise fault(errno.ESTALE)

    monkeypatch.setattr(ResultsWriter, "write_row", write_row)
    run = tmp_path / "run"
    argv = [*TRAIN, "--timesteps", "448", "--out", str(run)]  # the first episodes end at 400
    err = one_fault_line(capsys, train_cli.main, train_cli.PROG, argv)
    assert f": error: {run}: Stale file handle (ESTALE);" in err
    assert run_folder.read(run)["status"] == "failed"


def test_a_folder_gone_read_only_leaves_the_last_record_and_reads_as_stopped(
    tmp_path, capsys, monkeypatch
):
    """Nothing can be written any more, not even run.json: the last one written stays (it says
    running) and, its owner gone, the run shows as stopped unexpectedly."""
    run = tmp_path / "run"
    real, calls = tempfile.mkstemp, [0]

    def mkstemp(*args, **kwargs):
        if Path(kwargs["dir"]) == run and kwargs["prefix"] == ".checkpoint.zip.":
            calls[0] += 1
        if calls[0] >= 2:  # from the second checkpoint on, the folder refuses every new file
            raise fault(errno.EROFS)
        return real(*args, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    err = one_fault_line(capsys, train_cli.main, train_cli.PROG, [*TRAIN, "--out", str(run)])
    assert f"{run / 'checkpoint.zip'}: Read-only file system (EROFS);" in err
    record = run_folder.read(run)
    assert record["status"] == "running" and record["checkpoint"]["steps"] == 64
    assert run_folder.state_of(run, record["status"]) == run_folder.STOPPED


def warm_compiled_cache() -> None:
    """Compile (or load) the env's kernels here, so a subprocess under a file-size limit finds
    them in the cache instead of writing them."""
    env = make_vec(ID, 2)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()


def test_a_file_size_limit_fails_the_run_in_one_line(tmp_path):
    """``ulimit -f 16`` (16 KiB): run.json fits, the first checkpoint (28 KB) does not; the
    kernel refuses the write with EFBIG (Python ignores SIGXFSZ, which would kill it)."""
    warm_compiled_cache()
    limit = 16 * 1024

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    proc = start_training(tmp_path, ["--checkpoint-every", "64"], preexec_fn=limited)
    assert proc.wait(timeout=300) == cli.EXIT_FAULT, (tmp_path / "stderr.txt").read_text()
    err = (tmp_path / "stderr.txt").read_text()
    run = Path("run")  # the path as given (relative to the command's folder)
    assert err == (
        f"{train_cli.PROG}: error: {run / 'checkpoint.zip'}: File too large (EFBIG); {KEPT}\n"
    )
    record = run_folder.read(tmp_path / "run")
    assert record["status"] == "failed" and record["checkpoint"] is None
    assert not (tmp_path / "run" / "checkpoint.zip").exists() and no_partials(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a read-only folder anyway; "
                    "test_a_folder_gone_read_only_... injects the same fault")  # fmt: skip
def test_chmod_of_the_run_folder_mid_run_is_one_line(tmp_path):
    proc = start_training(tmp_path, ["--checkpoint-every", "64"])
    run = tmp_path / "run"
    try:
        wait_for_recorded_checkpoint(run, proc)
        run.chmod(0o555)
        assert proc.wait(timeout=120) == cli.EXIT_FAULT
    finally:
        run.chmod(0o755)
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
    err = (tmp_path / "stderr.txt").read_text()
    assert err.count("\n") == 1 and "Permission denied (EACCES)" in err and KEPT in err, err
    run_folder.load_model(run / "checkpoint.zip", "checkpoint")  # the last one: whole


def test_evaluate_keeps_the_old_table_when_the_new_one_cannot_be_written(
    tmp_path, capsys, monkeypatch
):
    table = write_text(tmp_path / "table.json", '{"old": true}\n')
    fail_fsync_of(monkeypatch, "table.json", errno.EFBIG)
    argv = ["--policy", "zero", "--episodes", "2", "--out", str(table)]
    err = one_fault_line(capsys, evaluate.main, evaluate.PROG, argv)
    assert f"{table}: File too large (EFBIG)" in err
    assert table.read_text() == '{"old": true}\n' and no_partials(tmp_path)


def test_evaluate_clip_in_a_folder_that_refuses_it(tmp_path, capsys, monkeypatch):
    real = tempfile.mkstemp

    def mkstemp(*args, **kwargs):
        if kwargs.get("prefix") == ".clip.gif.":
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(*args, **kwargs)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    argv = ["--policy", "zero", "--episodes", "1", "--gif", str(tmp_path / "clip.gif")]
    err = one_fault_line(capsys, evaluate.main, evaluate.PROG, argv)
    assert f"{tmp_path / 'clip.gif'}: Permission denied (EACCES)" in err


def test_main_job_fault_marks_the_job_failed_and_keeps_the_training(tmp_path, capsys, monkeypatch):
    out = tmp_path / "job"
    fail_fsync_of(monkeypatch, "clip.gif", errno.ENOSPC)
    argv = ["--env", ID, "--timesteps", "64", "--n-envs", "2", *TINY_SET, "--episodes", "2",
            "--no-progress", "--out", str(out)]  # fmt: skip
    err = one_fault_line(capsys, main_job.main, main_job.PROG, argv)
    assert f"{out / 'reorient-v0' / 'clip.gif'}: No space left on device (ENOSPC)" in err
    assert json.loads((out / main_job.RECORD).read_text())["status"] == "failed"
    assert run_folder.read(out / "reorient-v0")["status"] == "finished"  # the training: whole
    assert no_partials(out)


def test_bench_fault_is_one_line(tmp_path, capsys, monkeypatch):
    fail_fsync_of(monkeypatch, "accuracy.png", errno.ENOSPC)
    argv = ["accuracy", "--preset", "tiny", "--out", str(tmp_path)]
    err = one_fault_line(capsys, bench_cli.main, bench_cli.PROG, argv)
    assert f"{tmp_path / 'accuracy.png'}: No space left on device (ENOSPC)" in err
    assert json.loads((tmp_path / "accuracy.json").read_text())  # written before: whole
    assert no_partials(tmp_path)


# --- the plumbing ---------------------------------------------------------------------------------


def test_atomic_open_names_the_file_whatever_the_writer_made_of_the_fault(tmp_path, monkeypatch):
    """The temporary file on /dev/full: the kernel refuses its writes with ENOSPC; a writer
    that turns that into an exception of its own still ends in a WriteError naming the file."""
    path = write_text(tmp_path / "a.bin", "old")
    real = tempfile.mkstemp
    monkeypatch.setattr(
        tempfile, "mkstemp", lambda **kw: (os.open("/dev/full", os.O_WRONLY), str(kw["dir"]) + "/x")
    )

    class Full(Exception):
        pass

    def writer(f):
        try:
            f.write(b"x" * 10**6)
            f.flush()
        except OSError:
            raise Full("could not save") from None

    with pytest.raises(WriteError) as info, atomic_open(path) as f:
        writer(f)
    monkeypatch.setattr(tempfile, "mkstemp", real)
    assert info.value.errno == errno.ENOSPC and info.value.filename == str(path)
    assert isinstance(info.value.__cause__, Full)
    assert path.read_text() == "old" and list(tmp_path.iterdir()) == [path]


def test_atomic_open_lets_other_errors_of_the_block_through(tmp_path):
    path = tmp_path / "a.txt"
    with pytest.raises(FileNotFoundError) as info, atomic_open(path, "w"):
        (tmp_path / "missing.txt").read_text()  # another file: not a fault of this write
    assert info.value.filename == str(tmp_path / "missing.txt")
    with pytest.raises(KeyError), atomic_open(path, "w"):
        raise KeyError("a bug")
    assert list(tmp_path.iterdir()) == []
    # A folder that vanished: the write names the file it was for.
    with pytest.raises(WriteError) as gone:
        write_text(tmp_path / "gone" / "a.txt", "x")
    assert gone.value.errno == errno.ENOENT and gone.value.filename == str(tmp_path / "gone/a.txt")
    assert cli.is_fault(gone.value)


def test_only_faults_become_one_line_other_os_errors_keep_their_traceback():
    def missing(argv):
        Path("/no/such/file/anywhere").read_text()  # a bug of the package, say

    with pytest.raises(FileNotFoundError):
        cli.run(missing, "prog", [])
    for code in (errno.ENOSPC, errno.EFBIG, errno.EACCES, errno.EROFS, errno.ESTALE, errno.EIO):
        assert cli.is_fault(fault(code)), errno.errorcode[code]
    assert not cli.is_fault(fault(errno.ENOENT)) and not cli.is_fault(ValueError())


def test_entry_point_fault_exit_status_without_traceback(tmp_path):
    """End to end: ``ulimit -f`` under ``agents.evaluate --out``, a table larger than it."""
    warm_compiled_cache()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def limited() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (256, 256))

    table = tmp_path / "table.json"
    proc = subprocess.run(
        [sys.executable, "-m", "agents.evaluate", "--policy", "zero", "--episodes", "2",
         "--out", str(table)],
        env=env, capture_output=True, text=True, timeout=300, preexec_fn=limited,
    )  # fmt: skip
    assert proc.returncode == cli.EXIT_FAULT, proc.stderr[-3000:]
    assert proc.stderr == f"{evaluate.PROG}: error: {table}: File too large (EFBIG); {KEPT}\n"
    assert list(tmp_path.iterdir()) == []
