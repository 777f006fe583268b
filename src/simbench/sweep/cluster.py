"""Where `--ray` sends a sweep: 'local' (a cluster started here), a running cluster's HOST:PORT, or a Ray Client
address ray://HOST:PORT. An address of another form is refused before anything starts, and one that nothing
answers at within CONNECT_TIMEOUT seconds (a TCP connection to it: refused, no route, no such host) is refused
before the sweep's folder is made, in one line naming --ray (exit 2: the address is the user's to correct), rather
than left to Ray, which retries for minutes. Where something answers that is not a Ray cluster, Ray is asked to
try once (RAY_gcs_server_port_wait_time_s=1 unless set: about 40 s, with Ray's own warnings) and its refusal is
one line too (simbench.sweep.execute).
"""

from __future__ import annotations

import re
import socket

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


def reach(address: str) -> None:
    """Nothing for 'local' or an address that accepts a connection within CONNECT_TIMEOUT; ScenarioError naming
    --ray, the address and the reason otherwise (or for an address of the wrong form)."""
    where = check_address(address)
    if where is None:
        return
    try:
        socket.create_connection(where, timeout=CONNECT_TIMEOUT).close()
    except socket.gaierror as err:
        raise ScenarioError("--ray", None, f"no Ray cluster at {address}: no such host ({err.strerror}); "
                                           f"{_EXPECTED}") from None
    except TimeoutError:
        raise ScenarioError("--ray", None, f"no Ray cluster answers at {address} within {CONNECT_TIMEOUT:g} s; "
                                           f"{_EXPECTED}") from None
    except OSError as err:
        raise ScenarioError("--ray", None, f"no Ray cluster answers at {address}: {os_words(err)}; "
                                           f"{_EXPECTED}") from None
