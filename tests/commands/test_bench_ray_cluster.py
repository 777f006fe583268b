"""A bench on a Ray cluster of two nodes (issue 47): ray.cluster_utils' head and worker node on this machine, each
of one CPU and bound to 127.0.0.1, joined by its address as `--ray HOST:PORT` joins a cluster. The worker node is
lost in the middle of a run; the run runs again, and the bench writes the bytes of the same bench in two local
worker processes. A run whose worker process dies runs once more; one that kills it every time is its own
`crashed` row, not run for ever. Truths: the bench (or sweep) run in two local worker processes, the cluster's own
node ids, and the sockets the kernel lists for the cluster's processes (psutil).
"""

import csv
import io
import ipaddress
import json
import threading
import time
from pathlib import Path

import psutil
import pytest
import yaml
from simbench_planar3r import control as planar3r_control

from simbench.commands.bench import load_suite, run_bench
from simbench.commands.bench.methods import METHODS
from simbench.commands.bench.tasks import draw
from simbench.commands.sweep import load_sweep, run_sweep
from simbench.commands.sweep.cluster import _join_ray as join_ray  # joined as the bench joins: on loopback

ray = pytest.importorskip("ray", reason="the Ray extra is part of [test]; this check needs it")
from ray.cluster_utils import Cluster  # (after the skip where Ray is not installed)

NODE = {"num_cpus": 1, "node_ip_address": "127.0.0.1"}


TABLES = ("runs.csv", "leaderboard.csv", "leaderboard_by_kind.csv")
RUNNING = "ray::_run_on_node"  # a Ray worker's process title while it runs a run
LINE = planar3r_control.__file__.rsplit("/", 1)[0] + "/scenarios/line_policy.yaml"
DIES = """\
import os

import numpy as np


def make(scenario):
    if {always} or not os.path.exists({marker!r}):
        open({marker!r}, "a").close()
        os._exit(3)
    return lambda obs: np.zeros(3)
"""


def suite():
    """The planar 3R's suite, 3 tasks by 2 methods: 6 runs."""
    return load_suite("planar3r").with_options(tasks=3, methods=["dls_adaptive", "pinv"])


@pytest.fixture(scope="module")
def policies(tmp_path_factory):
    """A folder of two policy modules whose factory ends its process: `dies_once` the first time it is called (a
    marker file says it was), `dies_always` every time."""
    folder = tmp_path_factory.mktemp("policies")
    for name, always in (("dies_once", False), ("dies_always", True)):
        (folder / f"{name}.py").write_text(DIES.format(always=always, marker=str(folder / f"{name}.called")))
    return folder


@pytest.fixture(scope="module")
def cluster(policies):
    """A head node and a worker node on 127.0.0.1, their workers able to import the policies."""
    env = {"env_vars": {"PYTHONPATH": str(policies)}}
    nodes = Cluster(initialize_head=True, head_node_args={**NODE, **env, "include_dashboard": False})
    try:
        nodes.add_node(**NODE, **env)
        nodes.wait_for_nodes()
        yield nodes
    finally:
        ray.shutdown()
        nodes.shutdown()


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The bench in two local worker processes; its folder."""
    out = tmp_path_factory.mktemp("bench") / "workers2"
    run_bench(suite(), out, workers=2)
    return out


def _processes(cluster) -> list[psutil.Process]:
    """Every process of the cluster's nodes, the Ray workers their raylets started included."""
    found = []
    for node in cluster.list_all_nodes():
        for started in node.all_processes.values():
            for info in started:
                process = psutil.Process(info.process.pid)
                found += [process, *process.children(recursive=True)]
    return found


def _listening(pids: set[int]) -> set[str]:
    """The addresses the processes `pids` listen on, IPv4-mapped ones as IPv4."""
    addresses = set()
    for conn in psutil.net_connections("inet"):
        if conn.status == psutil.CONN_LISTEN and conn.pid in pids:
            address = ipaddress.ip_address(conn.laddr.ip)
            addresses.add(str(getattr(address, "ipv4_mapped", None) or address))
    return addresses


def _table(path) -> tuple[list[str], list[list[str]]]:
    """A CSV's header and rows, its wall_time column left out (the one column measured, not computed)."""
    header, *rows = list(csv.reader(io.StringIO(path.read_text())))
    kept = [i for i, name in enumerate(header) if name != "wall_time"]
    return [header[i] for i in kept], [[row[i] for i in kept] for row in rows]


def _rows(out) -> dict[str, dict]:
    return {row["id"]: row for row in (json.loads(p.read_text()) for p in (out / "rows").glob("*.json"))}


def _ran_on(out, node_id: str) -> bool:
    """Whether a run of the bench in `out` has its row, run on that node."""
    return (out / "rows").is_dir() and any(row.get("node") == node_id for row in _rows(out).values())


def _running_on(node) -> bool:
    """Whether a Ray worker of this node is running a run now."""
    raylet = psutil.Process(node.all_processes["raylet"][0].process.pid)
    for child in raylet.children(recursive=True):
        try:
            if child.cmdline()[:1] and child.cmdline()[0].startswith(RUNNING):
                return True
        except psutil.Error:  # ended meanwhile
            continue
    return False


def test_the_cluster_listens_on_loopback_alone(cluster):
    """Every socket a process of the cluster listens on is on 127.0.0.1."""
    processes = _processes(cluster)
    addresses = _listening({p.pid for p in processes})
    assert addresses and addresses == {"127.0.0.1"}, addresses


def _warm(node_id: str) -> None:
    """A Ray worker process of the node started and one task of the suite run in it by each method, as the bench's
    first runs there would: whatever a run imports or builds once a process (the pipeline, SciPy's LAPACK, the
    planar 3R's plugin, its compiled model) is then paid before the bench starts (the bench, joining the same
    connection, reuses the process)."""
    from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

    bench = suite()
    robot = bench.robots[0]
    task = draw(robot, 1, bench.seed)[0]
    documents = [(f"warm-{method}", METHODS[method].document(task, robot)) for method in bench.methods]

    @ray.remote(num_cpus=1, scheduling_strategy=NodeAffinitySchedulingStrategy(node_id, soft=False))
    def warm(documents: list) -> str:
        from simbench.commands import pipeline
        from simbench.scenario import parse_scenario

        for name, document in documents:
            pipeline._evaluate(parse_scenario(document, name))
        return ray.get_runtime_context().get_node_id()

    assert ray.get(warm.remote(documents)) == node_id


def test_a_bench_on_two_nodes_losing_one_mid_run_writes_the_bytes_of_two_local_workers(cluster, reference,
                                                                                        tmp_path, capsys):
    """The bench's runs spread over both nodes; once the worker node has finished a run and is running another, it
    is removed (its processes killed). The run it held runs again on the head, and runs.csv (but wall_time),
    leaderboard.csv and leaderboard_by_kind.csv equal those of the bench in two local worker processes.

    Both nodes' Ray workers are started and warmed first (_warm), on the connection the bench then joins: a worker
    node whose first run also paid its process's start, imports and first builds (seconds, on a loaded machine)
    could see the warm head run all the others meanwhile, and never run a second (seen in clean-clone CI runs with
    only the imports warmed: runs by node head 5, worker 1)."""
    worker = next(iter(cluster.worker_nodes))
    head_id, worker_id = cluster.head_node.node_id, worker.node_id
    out = tmp_path / "ray"
    lost, stop = threading.Event(), threading.Event()
    join_ray(cluster.address, 1)
    for node_id in (head_id, worker_id):
        _warm(node_id)

    def lose_the_worker_node() -> None:
        while not stop.is_set():
            if _ran_on(out, worker_id) and _running_on(worker):
                cluster.remove_node(worker)
                lost.set()
                return
            time.sleep(0.01)

    watcher = threading.Thread(target=lose_the_worker_node)
    watcher.start()
    try:
        result = run_bench(suite(), out, ray=cluster.address)
    finally:
        stop.set()
        watcher.join()
        ray.shutdown()
    said = capsys.readouterr().err
    ran = [("head" if row.get("node") == head_id else "worker") for row in _rows(out).values()]
    assert lost.is_set(), f"the worker node never ran a second run (runs by node: {sorted(ran)})"
    assert "lost with its Ray node" in said or "its Ray worker process died" in said, said
    assert result.summary["status"] == json.loads((reference / "summary.json").read_text())["status"]
    nodes = {run_id: row["node"] for run_id, row in _rows(out).items()}
    assert len(nodes) == 6 and set(nodes.values()) == {head_id, worker_id}, nodes
    for name in TABLES:
        assert _table(out / name) == _table(reference / name), name
    for name in TABLES[1:]:
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name


def test_a_run_whose_worker_dies_runs_once_more_and_one_that_always_kills_it_is_crashed(cluster, policies,
                                                                                        tmp_path, monkeypatch):
    """On the cluster, `dies_once`'s run runs again and has the row it has in a local worker process, once its
    marker is there; `dies_always`'s run is `crashed` after its second attempt."""
    base = yaml.safe_load(Path(LINE).read_text())
    base["timing"]["duration"] = 1.0
    (tmp_path / "line.yaml").write_text(yaml.safe_dump(base))
    (tmp_path / "sweep.yaml").write_text(yaml.safe_dump({
        "base": "line.yaml", "outputs": "none", "grid": {"control.policy": ["dies_once:make", "dies_always:make"]}}))
    sweep = load_sweep(str(tmp_path / "sweep.yaml"))
    on_ray = run_sweep(sweep, tmp_path / "ray", ray=cluster.address, allow_code=True)
    monkeypatch.syspath_prepend(str(policies))  # for the local workers, forked from this process
    local = run_sweep(sweep, tmp_path / "local", workers=2, allow_code=True)
    ray_rows, local_rows = _table(tmp_path / "ray" / "results.csv"), _table(tmp_path / "local" / "results.csv")
    assert ray_rows[0] == local_rows[0]
    once, always = ray_rows[1]
    assert once == local_rows[1][0]
    status, error = (always[ray_rows[0].index(name)] for name in ("status", "error"))
    assert (status, error) == ("crashed", "its Ray worker process died 2 times (WorkerCrashedError)")
    assert on_ray.summary["status"]["crashed"] == local.summary["status"]["crashed"] == 1
