"""A digest of every shipped scenario's outputs, to show that a change of code left them as they were.

For each scenario under scenarios/ it runs the pipeline without video and writes, per array of timeseries.npz,
the SHA-256 of its bytes (dtype and shape included), with the report's status and events. Run it on two
revisions and compare the files:

    python -m benchmarks.outputs_digest before.json      # on the old revision
    python -m benchmarks.outputs_digest after.json       # on the new one
    python -m benchmarks.outputs_digest --compare before.json after.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

import simbench
from simbench.core.resources import scenarios_dir


def digest(path: Path) -> dict:
    """Hashes of one scenario's timeseries arrays, and its status and event count."""
    with tempfile.TemporaryDirectory() as tmp:
        try:
            result = simbench.run(path, out=Path(tmp) / "out", video=False)
            report = result.report
        except simbench.PhysicsError:
            report = json.loads((Path(tmp) / "out" / "report.json").read_text())
        arrays = {}
        with np.load(Path(tmp) / "out" / "timeseries.npz") as npz:
            for name in sorted(npz.files):
                a = np.ascontiguousarray(npz[name])
                arrays[name] = hashlib.sha256(f"{a.dtype}{a.shape}".encode() + a.tobytes()).hexdigest()[:16]
    return {"status": report["status"], "events": len(report.get("events", [])), "arrays": arrays}


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.outputs_digest", description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", type=Path, help="the digest file to write")
    parser.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"), help="compare two digests")
    args = parser.parse_args(argv)
    if args.compare:
        before, after = (json.loads(p.read_text()) for p in args.compare)
        arrays = lambda digest, name: digest.get(name, {}).get("arrays", {})  # noqa: E731
        differ = [f"{name}: {key}" for name in sorted(before.keys() | after.keys())
                  for key in sorted(set(arrays(before, name)) | set(arrays(after, name)))
                  if arrays(before, name).get(key) != arrays(after, name).get(key)]
        differ += [f"{name}: status" for name in before if before[name]["status"] != after.get(name, {}).get("status")]
        print("\n".join(differ) or f"all {len(before)} scenarios equal, array by array")
        return 1 if differ else 0
    if args.out is None:
        parser.error("give the digest file to write, or --compare BEFORE AFTER")
    found = {str(p.relative_to(scenarios_dir()).with_suffix("")): digest(p)
             for p in sorted(scenarios_dir().glob("*/*.yaml"))}
    args.out.write_text(json.dumps(found, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
