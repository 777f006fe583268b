"""Every simbench module imports where the POSIX-only modules `fcntl` and `resource` do not exist (Windows): each
is imported where it is used, with a fallback (project issue 38). Only simbench's own imports of them fail here:
the libraries simbench uses import them on Linux from their Linux backends (psutil), which Windows does not load."""

import pkgutil
import subprocess
import sys

import simbench

PROBE = """
import builtins, importlib, sys
posix_only, real_import = {"fcntl", "resource"}, builtins.__import__

def windows_import(name, globals=None, locals=None, fromlist=(), level=0):
    if name in posix_only and (globals or {}).get("__name__", "").startswith("simbench"):
        raise ImportError(f"No module named {name!r}")  # as on Windows
    return real_import(name, globals, locals, fromlist, level)

builtins.__import__ = windows_import
failed = []
for name in sys.argv[1:]:
    try:
        importlib.import_module(name)
    except ImportError as err:
        failed.append(f"{name}: {err}")
print("\\n".join(failed))
"""


def test_every_module_imports_without_fcntl_and_resource():
    names = sorted(m.name for m in pkgutil.walk_packages(simbench.__path__, "simbench.")
                   if not m.name.endswith("__main__"))
    assert len(names) > 100
    done = subprocess.run([sys.executable, "-c", PROBE, *names], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "", done.stdout
