"""A reader that goes away (`simbench list | head -1`) stops simbench quietly, as it stops a shell tool: exit 141
(128 + SIGPIPE) and nothing on stderr, not an 'internal error'."""

import subprocess
import sys


def test_a_closed_pipe_ends_the_command_quietly():
    child = subprocess.Popen([sys.executable, "-P", "-m", "simbench", "list"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE)
    child.stdout.close()  # before simbench writes: its first write meets a pipe with no reader
    err = child.stderr.read().decode()
    assert child.wait(timeout=120) == 141, err
    assert err == ""
