"""Where `--ray` sends a sweep: 'local', a running cluster's HOST:PORT, or ray://HOST:PORT. An address of another
form, or one that refuses a TCP connection within CONNECT_TIMEOUT, is refused in one line naming --ray before the
sweep's folder is made, rather than left to Ray, which retries for minutes.
"""

from __future__ import annotations

import re
import socket

from simbench import extras
from simbench.errors import ScenarioError, os_words

CONNECT_TIMEOUT = 5.0  # s
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
