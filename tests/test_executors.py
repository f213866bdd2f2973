"""Executors (issue 15 item 4): the slicer's blocks and the Monte-Carlo runs on `inline`,
`processes` or a Dask cluster (a LocalCluster on 127.0.0.1 here), the same bytes whichever; an
unreachable scheduler, bad options and dying workers are one line and leave nothing behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from badinput import assert_rejected
from cooprint import executors
from cooprint.cli import main
from cooprint.config import load_settings
from cooprint.executors import (DaskExecutor, ExecutorError, InlineExecutor, ProcessExecutor, _ordered,
                                check_executor_options, parse_scheduler, stop_pool)
from cooprint.slicing import layer_tops, pack_layers, slice_chunks, unpack_layers
from cooprint.slicing.slicer import BLOCK, layer_range

from solids import COARSE, box, to_trimesh

SRC = Path(__file__).resolve().parents[1] / "src"
TESTS = Path(__file__).resolve().parent
COARSE_FLAGS = [a for k, v in COARSE.items() for a in ("--set", f"{k}={v}")]


@pytest.fixture(scope="module")
def worker_env():
    """Dask's scheduler and worker processes are new interpreters: they import this cooprint, not
    another one, and this module (whose functions the tasks below name)."""
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(SRC), str(TESTS)] + ([old] if old else []))
    yield
    if old is None:
        del os.environ["PYTHONPATH"]
    else:
        os.environ["PYTHONPATH"] = old


@pytest.fixture(scope="module")
def cluster(worker_env):
    """A LocalCluster of two worker processes on 127.0.0.1, for the module."""
    with DaskExecutor("local:2") as ex:
        yield ex


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    """A 40 x 1200 x 60 mm bar: 7 chunks for two robots, 60 layers each with COARSE (two blocks)."""
    path = tmp_path_factory.mktemp("bar") / "bar.stl"
    to_trimesh(box(40, 1200, 60)).export(path)
    return path


def _square(shared, task):
    return shared["k"] * task * task


def test_every_executor_gives_the_results_in_the_order_of_the_tasks(cluster):
    tasks = list(range(23))
    want = [3 * t * t for t in tasks]
    for ex in (InlineExecutor(), ProcessExecutor(2), cluster):
        assert list(ex.map(_square, tasks, shared={"k": 3}, window=3)) == want, ex.name
    assert cluster.slots == 2


def test_at_most_a_window_of_tasks_is_submitted_and_not_consumed():
    submitted, consumed = [], []

    def submit(t):
        submitted.append(t)
        return t

    for r in _ordered(submit, lambda f: f, list(range(10)), window=3):
        consumed.append(r)
        assert len(submitted) - len(consumed) <= 3
        assert len(submitted) == min(10, len(consumed) + 3)  # and the pipe is kept full
    assert consumed == list(range(10))


def test_packed_layers_unpack_to_equal_arrays(bar):
    from cooprint.io.mesh import load_mesh
    from cooprint.slicing import iter_layers
    from cooprint.config import SlicingSettings

    layers = list(iter_layers(load_mesh(bar), SlicingSettings(), workers=1))[:BLOCK]
    back = unpack_layers(pack_layers(layers + [layers[0].__class__.build(9.0, 0.2, [])]))
    for a, b in zip(layers, back):
        assert (a.z, a.height) == (b.z, b.height)
        for name in ("points", "offsets", "role", "width"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), name
    assert len(back[-1]) == 0 and back[-1].points.shape == (0, 2) and list(back[-1].offsets) == [0]


def test_slice_chunks_gives_the_same_layers_on_every_executor_even_for_one_chunk(cluster):
    """One chunk of 150 layers is several tasks (three blocks: two workers busy); its layers are the same on
    every executor, in order, with their indices."""
    from cooprint.io.mesh import Solid

    s = load_settings(overrides={"slicing.layer_height": 0.4, "slicing.first_layer_height": 0.4}).slicing
    mesh = to_trimesh(box(30, 40, 60))
    from cooprint.io.mesh import load_mesh

    path = Path(os.environ.get("TMPDIR", "/tmp")) / f"one_chunk_{os.getpid()}.stl"
    mesh.export(path)
    solid: Solid = load_mesh(path)
    path.unlink()
    first, end = layer_range(solid, s, 0.0)
    assert end - first == len(layer_tops(60.0, s)) == 150
    runs = {}
    for ex in (InlineExecutor(), ProcessExecutor(2), cluster):
        seen = []
        out = list(slice_chunks({"C": solid}, s, 0.0, lambda d, t: seen.append((d, t)), ex))
        assert [cid for cid, _ in out] == ["C"]
        assert [i for i, _ in out[0][1]] == list(range(150))
        assert seen[-1] == (150, 150) and len(seen) == -(-150 // BLOCK) == 3  # after every block
        runs[ex.name] = [(lp.z, lp.points.tobytes(), lp.offsets.tobytes(), lp.role.tobytes(), lp.width.tobytes())
                         for _, lp in out[0][1]]
    assert runs["inline"] == runs["processes"] == runs["dask"]


def _bundle_bytes(out: Path) -> dict[str, bytes]:
    files = sorted((out / "robots").iterdir()) + [out / "job.json"]
    return {f.name: f.read_bytes() for f in files}


def test_run_writes_the_same_bytes_on_every_executor(bar, cluster, tmp_path, worker_env):
    """`cooprint run` of a 7-chunk bar: robots/*.coop, *.gcode and job.json byte for byte the same
    inline, in processes, on a LocalCluster it starts (local:2) and on a running cluster
    (tcp://127.0.0.1:PORT)."""
    address = cluster.scheduler_address
    assert address.startswith("tcp://127.0.0.1:")
    outputs = {}
    for name, flags in (("inline", ["--executor", "inline"]), ("processes", []),
                        ("local", ["--executor", "dask", "--scheduler", "local:2"]),
                        ("tcp", ["--executor", "dask", "--scheduler", address])):
        out = tmp_path / name
        assert main(["run", str(bar), "--out", str(out), "-q", "--no-picture", *COARSE_FLAGS, *flags]) == 0, name
        outputs[name] = _bundle_bytes(out)
    assert set(outputs["inline"]) == {"A.coop", "A.gcode", "B.coop", "B.gcode", "job.json"}
    assert len(json.loads(outputs["inline"]["job.json"])["chunks"]) == 7
    for name in ("processes", "local", "tcp"):
        assert outputs[name] == outputs["inline"], name


def test_perturbed_runs_are_the_same_on_every_executor(cluster, tmp_path, capsys):
    from cooprint.simulation import load_inputs
    from cooprint.simulation.perturb import perturb_runs
    from solids import bar_bundle

    job = bar_bundle(tmp_path, 20.0)
    inp = load_inputs([str(job)])
    results = [perturb_runs(inp, 0.3, 4, seed=7, executor=ex).to_dict()
               for ex in (None, ProcessExecutor(2), cluster)]
    assert all(r == results[0] for r in results[1:])
    assert len({r["makespan_s"] for r in results[0]["per_run"]}) == 4  # four different runs
    # and through the command line, on a cluster of its own
    summaries = []
    for flags in (["--executor", "inline"], ["--executor", "dask", "--scheduler", "local:2"]):
        assert main(["simulate", str(job), "--perturb", "0.3", "--runs", "3", "-q", "--force", *flags]) == 0
        summaries.append(json.loads((job / "sim" / "summary.json").read_text())["perturb"])
    assert summaries[0] == summaries[1] and summaries[0]["runs"] == 3


# --- bad input ---------------------------------------------------------------------------------

@pytest.mark.parametrize("args, says", [
    (["--scheduler", "local:2"], "needs --executor dask"),
    (["--executor", "processes", "--scheduler", "tcp://127.0.0.1:8786"], "needs --executor dask"),
    (["--executor", "dask", "--scheduler", "local:0"], "local:N with N from 1 to 64"),
    (["--executor", "dask", "--scheduler", "local:two"], "expected tcp://HOST:PORT"),
    (["--executor", "dask", "--scheduler", "tcp://somehost"], "expected tcp://HOST:PORT"),
    (["--executor", "dask", "--scheduler", "127.0.0.1:8786"], "expected tcp://HOST:PORT"),
    (["--executor", "dask", "--scheduler", "tcp://h:99999"], "port 99999 out of range"),
    (["--executor", "threads"], "'threads' is not one of"),
])
def test_bad_executor_options_are_refused_before_the_work(bar, tmp_path, capsys, args, says):
    start = time.monotonic()
    assert_rejected(["run", str(bar), "--out", tmp_path / "out", *args], capsys, watch=[tmp_path], contains=says)
    assert time.monotonic() - start < 2.0


def test_simulate_takes_an_executor_only_for_perturbed_runs(tmp_path, capsys):
    from solids import bar_bundle

    job = bar_bundle(tmp_path, 20.0)
    assert_rejected(["simulate", job, "--executor", "dask"], capsys, watch=[tmp_path],
                    contains="--executor runs the --perturb runs")
    assert_rejected(["simulate", job, "--perturb", "0.2", "--scheduler", "local:2"], capsys, watch=[tmp_path],
                    contains="needs --executor dask")


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:9", "tcp://no-such-host.invalid:8786"])
def test_a_scheduler_that_does_not_answer_is_one_line_within_seconds(bar, tmp_path, capsys, address, monkeypatch):
    """Nothing listening (port 9), or a host that cannot be resolved: one line after the
    connection timeout (5 s; 1 s for the second case, to save time), exit 2, nothing written."""
    if "invalid" in address:
        monkeypatch.setattr(executors, "CONNECT_TIMEOUT", 1.0)
    start = time.monotonic()
    line = assert_rejected(["run", str(bar), "--out", tmp_path / "out", "--executor", "dask", "--scheduler", address],
                           capsys, watch=[tmp_path], contains=f"--scheduler {address}: no Dask scheduler answered")
    assert f"within {executors.CONNECT_TIMEOUT:g} s" in line
    assert time.monotonic() - start < executors.CONNECT_TIMEOUT + 5
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("answer", [None, b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n"],
                         ids=["silent", "web-server"])
def test_something_that_is_not_a_scheduler_is_one_line_not_a_hang(bar, tmp_path, capsys, answer, monkeypatch):
    """A port that takes the connection and stays silent (Dask's handshake waits for ever) or
    answers as a web server does (Dask reads its bytes as a message length): one line, exit 2,
    nothing written, within the timeout and its margin."""
    import socket
    import threading

    monkeypatch.setattr(executors, "CONNECT_TIMEOUT", 1.0)
    monkeypatch.setattr(executors, "CONNECT_MARGIN", 1.0)
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    held = []

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)
            if answer is not None:
                try:
                    conn.recv(64)
                    conn.sendall(answer)
                    conn.close()
                except OSError:
                    pass

    threading.Thread(target=serve, daemon=True).start()
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    start = time.monotonic()
    try:
        line = assert_rejected(["run", str(bar), "--out", tmp_path / "out", "--executor", "dask", "--scheduler",
                                address], capsys, watch=[tmp_path])
    finally:
        server.close()
        for conn in held:
            conn.close()
    assert f"--scheduler {address}:" in line and ("not a Dask scheduler" in line or "not answer as a Dask" in line)
    assert time.monotonic() - start < 10


def test_without_dask_installed_the_dask_executor_says_how_to_get_it(bar, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    assert_rejected(["run", str(bar), "--out", tmp_path / "out", "--executor", "dask"], capsys, watch=[tmp_path],
                    contains="pip install 'cooprint[dask]'")


def test_check_executor_options():
    assert check_executor_options(None, None) == ("processes", None)
    assert check_executor_options("dask", None)[1].startswith("local:")
    assert check_executor_options("dask", "tcp://[::1]:8786") == ("dask", "tcp://[::1]:8786")
    assert parse_scheduler("local:3") == ("local", "3")
    with pytest.raises(ExecutorError, match="needs --executor dask"):
        check_executor_options("inline", "local:2")


# --- workers that die ----------------------------------------------------------------------------

def _die_in_worker(shared, task):
    os._exit(3)


def test_a_worker_process_that_dies_fails_the_run_with_one_line_and_no_bundle(bar, tmp_path, capsys, monkeypatch):
    """processes: a block whose worker dies (as the out-of-memory killer does) ends the job with
    one line, exit 2, and no bundle."""
    import cooprint.slicing.slicer as slicer

    monkeypatch.setattr(slicer, "_chunk_block", _die_in_worker)
    assert_rejected(["run", str(bar), "--out", tmp_path / "out", *COARSE_FLAGS], capsys, watch=[tmp_path],
                    contains="a worker process died during the job")
    assert not (tmp_path / "out").exists()


def _kill_once(shared, task):
    """Kill this worker process the first time any worker runs a task; then compute."""
    marker = Path(shared["marker"])
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return task * 10
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)


def _kill_always(shared, task):
    os.kill(os.getpid(), signal.SIGKILL)


def test_dask_retries_the_task_of_a_worker_that_died(cluster, tmp_path):
    """A worker killed under a task: its nanny starts a new one and the scheduler runs the task
    again; the results are whole and in order."""
    out = list(cluster.map(_kill_once, list(range(6)), shared={"marker": str(tmp_path / "killed")}))
    assert (tmp_path / "killed").exists()
    assert out == [10 * t for t in range(6)]


def test_a_task_that_kills_every_worker_is_one_clear_error(worker_env, tmp_path, monkeypatch):
    monkeypatch.setenv("DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES", "0")  # the helper's scheduler: no retry
    with DaskExecutor("local:1") as ex:
        with pytest.raises(ExecutorError, match="a task killed every worker that ran it"):
            list(ex.map(_kill_always, [1, 2, 3], shared={}))


# --- Ctrl-C --------------------------------------------------------------------------------------

def _tagged(tag: str) -> list[int]:
    """The processes whose environment holds ``COOPRINT_TEST_TAG=tag`` (zombies have none)."""
    found = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/environ", "rb") as f:
                if f"COOPRINT_TEST_TAG={tag}".encode() in f.read().split(b"\0"):
                    found.append(int(pid))
        except OSError:
            pass
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_stops_the_local_cluster_and_its_workers(bar, tmp_path):
    """`run --executor dask --scheduler local:2` interrupted while it starts its cluster and
    while it slices, as a terminal does (the signal to the whole group): exit 130, one line, no
    bundle, and no process of it left: the cluster's helper and its workers included, although
    they run in a session of their own."""
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    fine = ["--set", "slicing.layer_height=0.2"]
    # when the helper has started (its cluster starting), and when the workers slice
    for k, (processes, delay) in enumerate(((2, 0.3), (4, 2.0))):
        tag = f"{os.getpid()}-{k}"
        p = subprocess.Popen([sys.executable, "-m", "cooprint", "run", str(bar), "--out", f"r{k}", "-q", "--no-picture",
                              "--executor", "dask", "--scheduler", "local:2", *fine], cwd=tmp_path,
                             env=dict(env, COOPRINT_TEST_TAG=tag), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             start_new_session=True)
        end = time.monotonic() + 60
        while len(_tagged(tag)) < processes and time.monotonic() < end:
            time.sleep(0.05)
        time.sleep(delay)
        assert p.poll() is None, p.communicate()
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=60)
        err = err.decode()
        assert p.returncode == 130, (delay, p.returncode, err[-2000:])
        assert [ln for ln in err.splitlines() if ln.strip()] == ["cooprint: interrupted"], err[-2000:]
        end = time.monotonic() + 10
        while _tagged(tag) and time.monotonic() < end:
            time.sleep(0.1)
        assert _tagged(tag) == [], f"processes of the run interrupted after {delay} s are left"
        assert not (tmp_path / f"r{k}").exists()


def test_the_local_cluster_ends_with_a_killed_parent(bar, tmp_path):
    """kill -9 of `cooprint run --executor dask`: its helper and the workers end too."""
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    tag = f"{os.getpid()}-killed"
    p = subprocess.Popen([sys.executable, "-m", "cooprint", "run", str(bar), "--out", "r", "-q", "--no-picture",
                          "--executor", "dask", "--scheduler", "local:2", "--set", "slicing.layer_height=0.2"],
                         cwd=tmp_path, env=dict(env, COOPRINT_TEST_TAG=tag), stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL, start_new_session=True)
    end = time.monotonic() + 30
    while len(_tagged(tag)) < 4 and time.monotonic() < end:  # the command, the helper, two workers
        time.sleep(0.2)
    assert len(_tagged(tag)) >= 4
    p.kill()
    p.wait()
    end = time.monotonic() + 15
    while _tagged(tag) and time.monotonic() < end:
        time.sleep(0.1)
    assert _tagged(tag) == []


def _echo(shared, task):
    return task


def test_stopping_a_pool_mid_result_leaves_no_thread_waiting_for_it():
    """A worker stopped while it sends a result leaves the pool's thread reading the rest of it;
    stop_pool ends that wait, so that nothing is left to hang the interpreter's exit (Python
    waits for that thread when it exits). Here the half-sent result is written by hand."""
    import multiprocessing
    import struct
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork"))
    assert pool.submit(_echo, None, 7).result(timeout=30) == 7
    manager = pool._executor_manager_thread
    before = {p.pid for p in multiprocessing.active_children()} - {p.pid for p in pool._processes.values()}
    # the start of a 1,000-byte result (the pipe's framing: its length, then the bytes), cut short
    os.write(pool._result_queue._writer.fileno(), struct.pack("!i", 1000) + b"x" * 10)
    time.sleep(0.2)
    assert manager.is_alive()  # waiting for the 990 bytes more
    started = time.monotonic()
    stop_pool(pool)
    assert time.monotonic() - started < 5
    assert not manager.is_alive()
    assert {p.pid for p in multiprocessing.active_children()} <= before
