"""The design search on Dask (issue 16): the same log as ``tdpcr-optim`` with 1 and 2
threads and on clusters of 1 and 2 workers; a driver killed with SIGKILL and resumed
ends with the same log without evaluating a logged candidate again; a worker killed
mid-evaluation has its task run on the other worker, with no duplicate or missing log
line. Real processes: a ``dask scheduler`` and two ``dask worker`` on 127.0.0.1, all
ended by the fixture's teardown."""

import json
import os
import pathlib
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

distributed = pytest.importorskip("distributed")

from optim_tasks import slow_evaluate  # noqa: E402
from tdpcr.optim import DesignSearch, run  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
CONFIG = HERE / "data" / "tiny_search.ron"
BUDGET = "4"
SEED = "9"
#: Bound of every wait on a process [s].
TIMEOUT_S = 90


def records(out):
    """The log's records in file order, without their wall times (the only field that is
    not a function of config and seed)."""
    lines = (pathlib.Path(out) / "evaluations.jsonl").read_text().splitlines()
    out = [json.loads(line) for line in lines]
    for r in out:
        del r["eval_time_s"]
    return out


def by_id(rs):
    return sorted(rs, key=lambda r: r["id"])


@pytest.fixture(scope="module")
def optim_bin():
    """The `tdpcr-optim` binary: $TDPCR_OPTIM_BIN, or beside $TDPCR_BIN, else built by
    cargo."""
    if "TDPCR_OPTIM_BIN" in os.environ:
        return os.environ["TDPCR_OPTIM_BIN"]
    if "TDPCR_BIN" in os.environ:
        path = pathlib.Path(os.environ["TDPCR_BIN"]).with_name("tdpcr-optim")
        if path.exists():
            return str(path)
    subprocess.run(
        ["cargo", "build", "--quiet", "-p", "tdpcr-optim", "--bin", "tdpcr-optim"], cwd=ROOT, check=True
    )
    return str(ROOT / "target" / "debug" / "tdpcr-optim")


@pytest.fixture(scope="module")
def embedded(optim_bin, tmp_path_factory):
    """The logs of tdpcr-optim with 1 and 2 rayon threads."""
    logs = {}
    for threads in (1, 2):
        out = tmp_path_factory.mktemp(f"embedded{threads}") / "run"
        subprocess.run(
            [optim_bin, str(CONFIG), "--budget-evals", BUDGET, "--seed", SEED, "--out", str(out)],
            env={**os.environ, "RAYON_NUM_THREADS": str(threads)},
            check=True,
            capture_output=True,
            timeout=TIMEOUT_S,
        )
        logs[threads] = out
    return logs


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def dask_cli():
    return str(pathlib.Path(sys.executable).with_name("dask"))


def end(process):
    if process.poll() is None:
        process.kill()
    process.wait(timeout=TIMEOUT_S)


class Cluster:
    """A `dask scheduler` and named `dask worker` processes (no nanny: a SIGKILL ends
    the worker itself), started on 127.0.0.1 and all killed by `close`."""

    def __init__(self, tmp, workers=2):
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.markers = tmp / "markers"
        self.markers.mkdir()
        self.env = {
            **os.environ,
            "PYTHONPATH": os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]),
            "TDPCR_TEST_MARKERS": str(self.markers),
            "RAYON_NUM_THREADS": "1",
        }
        self.log = open(tmp / "cluster.log", "wb")
        self.scheduler = None
        self.workers = {}
        port = self.address.rsplit(":", 1)[1]
        self.scheduler = self._start(
            ["scheduler", "--host", "127.0.0.1", "--port", port, "--no-dashboard"]
        )
        for i in range(workers):
            name = f"w{i}"
            self.workers[name] = self._start(
                ["worker", self.address, "--name", name, "--nthreads", "1", "--no-nanny",
                 "--host", "127.0.0.1", "--no-dashboard"]
            )
        with distributed.Client(self.address, timeout=TIMEOUT_S) as c:
            c.wait_for_workers(workers, timeout=TIMEOUT_S)

    def _start(self, args):
        return subprocess.Popen(
            [dask_cli(), *args], env=self.env, cwd=HERE, stdout=self.log, stderr=self.log,
            stdin=subprocess.DEVNULL,
        )

    def close(self):
        for p in [*self.workers.values(), self.scheduler]:
            if p is not None:
                end(p)
        self.log.close()


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    c = None
    try:
        c = Cluster(tmp_path_factory.mktemp("cluster"))
        yield c
    finally:
        if c is not None:
            c.close()


def driver(out, *extra):
    return [sys.executable, "-m", "tdpcr.optim", str(CONFIG), "--budget-evals", BUDGET,
            "--seed", SEED, "--out", str(out), *extra]


def test_the_cluster_gives_the_embedded_log_with_1_and_2_workers(embedded, cluster, tmp_path):
    reference = by_id(records(embedded[1]))
    assert len(reference) == int(BUDGET) + 1
    assert by_id(records(embedded[2])) == reference
    pareto = (embedded[1] / "pareto.csv").read_text()
    runs = {
        "1 local worker": driver(tmp_path / "local1", "--local-workers", "1"),
        "2 workers": driver(tmp_path / "cluster2", "--scheduler", cluster.address),
    }
    for what, command in runs.items():
        done = subprocess.run(command, capture_output=True, text=True, timeout=TIMEOUT_S)
        assert done.returncode == 0, f"{what}: {done.stderr}"
        out = pathlib.Path(command[command.index("--out") + 1])
        logged = records(out)
        # Only the driver writes, in candidate order: the file is already sorted by id.
        assert logged == reference, what
        assert (out / "pareto.csv").read_text() == pareto, what
        for name in ("report.md", "run.ron", "best_composite.ron"):
            assert (out / name).exists(), (what, name)


def test_a_killed_driver_resumes_to_the_same_log_without_evaluating_again(
    embedded, cluster, tmp_path
):
    reference = by_id(records(embedded[1]))
    out = tmp_path / "run"
    log = out / "evaluations.jsonl"
    p = subprocess.Popen(driver(out, "--scheduler", cluster.address),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        # Killed once the reference and the first generation (1 + 2 lines) are logged.
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline and p.poll() is None:
            if log.exists() and len(log.read_text().splitlines()) >= 3:
                break
            time.sleep(0.005)
        p.send_signal(signal.SIGKILL)
    finally:
        end(p)
    logged_before = len(log.read_text().splitlines())
    assert 3 <= logged_before < len(reference), "the kill came too late to test a resume"
    done = subprocess.run(driver(out, "--scheduler", cluster.address, "--resume"),
                          capture_output=True, text=True, timeout=TIMEOUT_S)
    assert done.returncode == 0, done.stderr
    assert records(out) == reference
    # The candidates logged before the kill were not evaluated again.
    evaluated_now = len(reference) - logged_before
    assert f"({evaluated_now} evaluated now)" in done.stdout, done.stdout


def test_a_worker_killed_mid_evaluation_has_its_task_run_elsewhere(embedded, cluster, tmp_path):
    reference = by_id(records(embedded[1]))
    out = tmp_path / "run"
    search = DesignSearch(str(CONFIG), str(out), seed=int(SEED), budget_evals=int(BUDGET))
    victim = cluster.workers["w0"]
    with distributed.Client(cluster.address, timeout=TIMEOUT_S) as client:
        # Kill w0 as soon as it has started a candidate (not the reference, which runs
        # alone): the candidate is mid-evaluation (each task waits 1 s first).
        killed = []

        def killer():
            deadline = time.monotonic() + TIMEOUT_S
            while time.monotonic() < deadline:
                started = [m.name for m in cluster.markers.iterdir()]
                mine = [m for m in started if m.endswith(f"-{victim.pid}") and not m.startswith("0-")]
                if mine:
                    victim.send_signal(signal.SIGKILL)
                    killed.extend(int(m.split("-")[0]) for m in mine)
                    return
                time.sleep(0.01)

        t = threading.Thread(target=killer)
        t.start()
        try:
            evaluations = run(search, client, task=slow_evaluate)
        finally:
            t.join(timeout=TIMEOUT_S)
    search.finish("test", 2)
    assert killed, "w0 started no candidate"
    assert victim.wait(timeout=TIMEOUT_S) == -signal.SIGKILL
    survivor = cluster.workers["w1"].pid
    started = {m.name for m in cluster.markers.iterdir()}
    for cid in killed:
        # The candidate the killed worker was evaluating ran again on the other worker.
        assert f"{cid}-{survivor}" in started, (cid, sorted(started))
    # Each candidate told once: no duplicate and no missing line.
    assert evaluations == len(reference)
    assert records(out) == reference
