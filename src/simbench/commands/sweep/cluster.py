"""A sweep's or a bench's runs on Ray (`--ray`): the address checked, the cluster joined (or, for 'local', started
on this machine's loopback), each run a Ray task spread over the nodes, and a run Ray lost run again.

The address is 'local', a running cluster's HOST:PORT, or ray://HOST:PORT. An address of another form, or one that
refuses a TCP connection within CONNECT_TIMEOUT, is refused in one line naming --ray before the sweep's folder is
made, rather than left to Ray, which retries for minutes.

A run lost with its node (Ray's NodeDiedError, or its result lost with the node: ObjectLostError) is not the run's
fault: it runs again, up to NODE_RERUNS times. A run whose worker process died (WorkerCrashedError, or a kill by
Ray's memory monitor: OutOfMemoryError) may be the node's fault or the run's own: it runs once more (CRASH_RERUNS),
and a second death is the run's `crashed` row, as a local worker's death is at once. Every attempt runs the same
document, so a run that ran again has the row it would have had.
"""

from __future__ import annotations

import ipaddress
import os
import re
import socket
import sys
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, nullcontext

from simbench.commands.sweep.execute import Task, crashed, run_variant
from simbench.core import extras
from simbench.core.errors import RunError, ScenarioError, os_words, printable

CONNECT_TIMEOUT = 5.0  # s
NODE_RERUNS = 3  # times a run lost with its node runs again
CRASH_RERUNS = 1  # times a run whose worker process died runs again
_HOST = re.compile(r"\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?")
_EXPECTED = "expected local, a running cluster's HOST:PORT (e.g. 10.0.0.5:6379) or ray://HOST:PORT"


def check_address(address: str) -> tuple[str, int] | None:
    """(host, port) of a cluster's address, None for 'local'; ScenarioError naming --ray for any other form."""
    if address == "local":
        return None
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not (_HOST.fullmatch(host) and port.isascii() and port.isdigit() and 0 < int(port) < 65536):
        raise ScenarioError("--ray", None, f"{_EXPECTED}, got {address!r}")
    return host.strip("[]"), int(port)


def check_where(workers: int | None, address: str | None) -> None:
    """The --workers and --ray arguments of a command that runs many runs (sweep, bench): ScenarioError naming the
    one that cannot be, before anything runs."""
    if workers is not None and workers < 1:
        raise ScenarioError("--workers", None, f"expected a number of processes >= 1, got {workers}")
    if address is not None:
        check_address(address)
        extras.require("ray", "running the runs on Ray", "--ray")


def reach(address: str) -> None:
    """ScenarioError naming --ray unless the address is 'local' or accepts a connection within CONNECT_TIMEOUT."""
    where = check_address(address)
    if where is None:
        return
    try:
        socket.create_connection(where, timeout=CONNECT_TIMEOUT).close()
        return
    except socket.gaierror as err:
        problem = f"no Ray cluster at {address}: no such host ({err.strerror})"
    except TimeoutError:
        problem = f"no Ray cluster answers at {address} within {CONNECT_TIMEOUT:g} s"
    except OSError as err:
        problem = f"no Ray cluster answers at {address}: {os_words(err)}"
    raise ScenarioError("--ray", None, f"{problem}; {_EXPECTED}")


def on_ray(tasks: Iterable[Task], address: str, workers: int, stream=None) -> Iterator[tuple[int, dict]]:
    """Every run as a Ray task, spread over the cluster's nodes, each outcome naming the node it ran on (`node`,
    Ray's node id); 'local' starts (and stops) a cluster here with `workers` CPUs. A run Ray lost runs again (see
    the module's note), said in a line on `stream` (stderr). Every node needs simbench, and with outputs: full a
    filesystem it shares."""
    import ray
    from tqdm import tqdm

    started = _join_ray(address, workers)
    remote = ray.remote(num_cpus=1, max_retries=0, scheduling_strategy="SPREAD")(_run_on_node)
    reruns = _Reruns()
    pending: dict = {}  # Ray's reference -> (run index, run_variant's arguments)

    def submit(index: int, kwargs: dict) -> None:
        pending[remote.remote(**kwargs)] = (index, kwargs)

    for task in tasks:
        submit(*task)
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                index, kwargs = pending.pop(ref)
                try:
                    outcome = ray.get(ref)
                except ray.exceptions.RayError as err:
                    again, words = reruns.judge(index, err)
                    if again:
                        tqdm.write(f"warning: {kwargs['source']}: {words}", file=stream or sys.stderr)
                        submit(index, kwargs)
                        continue
                    outcome = crashed(words)
                yield index, outcome
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def _run_on_node(**kwargs) -> dict:
    """run_variant's outcome on a Ray node, naming the node (Ray's node id, hex)."""
    import ray

    return {**run_variant(**kwargs), "node": ray.get_runtime_context().get_node_id()}


class _Reruns:
    """The attempts of each run that Ray lost, by cause, and whether the run may run again."""

    def __init__(self):
        self.lost: Counter = Counter()  # (run index, cause) -> attempts lost

    def judge(self, index: int, err: Exception) -> tuple[bool, str]:
        """(True, what happened) where the run may run again after `err`, else (False, its `crashed` error)."""
        import ray.exceptions

        name = type(err).__name__
        if isinstance(err, (ray.exceptions.NodeDiedError, ray.exceptions.ObjectLostError)):
            cause, bound, said = "node", NODE_RERUNS, "lost with its Ray node"
        elif isinstance(err, (ray.exceptions.WorkerCrashedError, ray.exceptions.OutOfMemoryError)):
            cause, bound, said = "worker", CRASH_RERUNS, "its Ray worker process died"
        else:
            return False, f"its Ray worker failed ({name})"
        self.lost[index, cause] += 1
        times = self.lost[index, cause]
        if times > bound:
            return False, f"{said} {times} times ({name})"
        return True, f"{said} ({name}): running it again ({times} of {bound})"


def _join_ray(address: str, workers: int) -> bool:
    """Connect to Ray unless already connected ('local': start a cluster here); whether this call connected. A
    cluster that cannot start is a RunError, one that cannot be joined a ScenarioError naming --ray."""
    import ray

    if ray.is_initialized():
        return False
    options = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
    try:
        with _loopback_node() if _on_loopback(address) else nullcontext():
            if address == "local":  # a new cluster whatever RAY_ADDRESS names
                ray.init(address="local", num_cpus=workers, **options)
            else:  # one attempt to join (long where a port answers that is not Ray's), not Ray's twenty
                os.environ.setdefault("RAY_gcs_server_port_wait_time_s", "1")
                ray.init(address=address, **options)
    except Exception as err:  # noqa: BLE001  Ray's refusal, whatever its type, in one line
        reason = printable(str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__)
        if address == "local":
            raise RunError(f"could not start a Ray cluster here: {reason}") from None
        raise ScenarioError("--ray", None, f"could not join the Ray cluster at {address}: {reason}") from None
    if address == "local":
        _check_loopback(ray)
    return True


def _on_loopback(address: str) -> bool:
    """Whether the address is 'local' or its host this machine's loopback (127.0.0.1, ::1, localhost)."""
    where = check_address(address)
    if where is None:
        return True
    try:
        return ipaddress.ip_address(where[0]).is_loopback
    except ValueError:
        return where[0] == "localhost"


@contextmanager
def _loopback_node() -> Iterator[None]:
    """Ray's switch for a cluster of this machine alone, off while `ray.init` starts one or joins one on the
    loopback address. Started, its node takes 127.0.0.1 and its services listen there alone, as on macOS and
    Windows; on Linux Ray would take the network interface's address and open them to the network. Joined, the
    address stays 127.0.0.1; on Linux Ray would swap it for the interface's, where such a cluster does not listen.
    Ray reads the switch (the variable RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER) from the environment when first imported,
    hence its module's constant; restored after, for a cluster joined later in this process."""
    from ray._private import ray_constants

    saved = ray_constants.ENABLE_RAY_CLUSTER
    ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        ray_constants.ENABLE_RAY_CLUSTER = saved


def _check_loopback(ray) -> None:
    """RunError, the cluster stopped, unless every node of the cluster started here is on a loopback address (a
    Ray whose switch no longer works)."""
    nodes = sorted({node["NodeManagerAddress"] for node in ray.nodes()})
    if not all(ipaddress.ip_address(node).is_loopback for node in nodes):
        ray.shutdown()
        raise RunError(f"the Ray cluster started here is on {', '.join(nodes)}, not on the loopback address alone: "
                       "stopped rather than left open to the network (a Ray release simbench does not know?)")
