"""A sweep's output folder (sweep.json, rows/<id>.json as each run ends, runs/<id>/, then the table), kept so that
the same sweep run again skips every run that has a row (rows are trusted: after changing simbench itself, start
over with `force`).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any, NoReturn

from simbench.commands.sweep.spec import Sweep, Variant
from simbench.core import destination
from simbench.core.atomic import write_text
from simbench.core.errors import OutputError, ScenarioError, destination_error, output_error
from simbench.outputs.report import plain, write_report

# What a sweep that cannot write a row keeps.
_KEPT = "the rows of the finished runs are kept: run the same command again to resume"

# What a sweep writes into its folder once every run has a row (plots/ holds a marker of its own).
RESULTS = ("results.csv", "results.parquet", "summary.json", "index.html")


class Store:
    """The rows of a sweep's finished runs, on disk."""

    def __init__(self, out: Path, sweep: Sweep, force: bool = False):
        self.out = out
        self.sweep = sweep
        self._lock = ExitStack()
        self._lock.enter_context(destination.locked(out))  # held until close()
        try:
            with destination.refused(out):
                self._prepare(force)
        except BaseException:
            self.close()
            raise

    def _prepare(self, force: bool) -> None:
        """Check the folder, clear it (force) or keep it to resume, and write the manifest and marker."""
        out, sweep = self.out, self.sweep
        destination.check_inputs(out, [p for p in (Path(sweep.source), Path(sweep.base)) if p.is_file()])
        fingerprint = sweep.fingerprint()
        self._clear_or_keep(force, fingerprint)
        created = not out.exists()
        try:
            self._start_folder(fingerprint)
        except (OSError, OutputError) as err:
            if not created:
                raise
            shutil.rmtree(out, ignore_errors=True)  # it holds nothing but what this call began to write
            if isinstance(err, OSError):
                raise destination_error(out, err) from None
            raise OutputError(err.path, err.problem, f"nothing was written to {out}") from None

    def _clear_or_keep(self, force: bool, fingerprint: str) -> None:
        """Empty a non-empty folder (with force, if simbench wrote it all) or keep it to resume this sweep;
        ScenarioError for other results without force."""
        out = self.out
        if not (out.exists() and any(p.name != destination.MARKER for p in out.iterdir())):
            return
        if force:
            destination.check_replace(out, removes=True)
            shutil.rmtree(out)
        elif _manifest_field(out / "sweep.json", "fingerprint") != fingerprint:
            _refuse_other_results(out)
        else:
            destination.check_replace(out, "a sweep resumed here rewrites its own files, and never yours")

    def _start_folder(self, fingerprint: str) -> None:
        """Create the folder, its manifest (first: it marks the folder as this sweep's), its marker and rows/."""
        out, sweep, manifest = self.out, self.sweep, self.out / "sweep.json"
        out.mkdir(parents=True, exist_ok=True)
        if not manifest.exists():
            write_text(manifest, json.dumps({
                "name": sweep.name, "source": sweep.source, "base": str(sweep.base), "fingerprint": fingerprint,
                "spec": sweep.spec.model_dump(mode="json"),
                "runs": [{"run": v.index, "id": v.id, "params": v.params} for v in sweep.variants],
            }, indent=1) + "\n")
        if not (out / destination.MARKER).exists():
            destination.mark(out, [manifest.name])
        (out / "rows").mkdir(exist_ok=True)

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Let another sweep write into the folder."""
        self._lock.close()

    def finished(self) -> dict[int, dict]:
        """Rows already on disk, by run index (a row that cannot be read is run again)."""
        rows = {}
        for variant in self.sweep.variants:
            path = self.out / "rows" / f"{variant.id}.json"
            try:
                row = json.loads(path.read_text())
            except (OSError, ValueError):
                continue
            if row.get("id") == variant.id:
                rows[variant.index] = row
        return rows

    def record(self, variant: Variant, outcome: dict) -> dict:
        """Write a finished run's row (and its report, if kept) and return the row; on Ray, the row names the node
        the run ran on (`node`, Ray's node id)."""
        with self.writing():
            row_file = self.out / "rows" / f"{variant.id}.json"
            if outcome.get("report") is not None:
                folder = run_folder(self.out, variant.id)
                destination.mark_more(self.out, [(folder / "report.json").relative_to(self.out).as_posix()])
                folder.mkdir(parents=True, exist_ok=True)
                write_report(outcome["report"], folder / "report.json")
            node = {"node": outcome["node"]} if "node" in outcome else {}
            row = plain({"run": variant.index, "id": variant.id, "params": variant.params,
                         "status": outcome["status"], "error": outcome["error"], "metrics": outcome["metrics"],
                         "wall_time": outcome["wall_time"], **node})
            destination.mark_more(self.out, [row_file.relative_to(self.out).as_posix()])
            write_text(row_file, json.dumps(row, allow_nan=False) + "\n")
        return row

    def claim(self, names: tuple[str, ...]) -> None:
        """List files about to be written into the folder in its marker (destination.mark_more)."""
        with self.writing():
            destination.mark_more(self.out, names)

    @contextmanager
    def writing(self) -> Iterator[None]:
        """A write once runs have started: a refusal is OutputError saying that the rows so far are kept."""
        try:
            yield
        except OSError as err:
            raise output_error(err, self.out, _KEPT) from None
        except OutputError as err:
            raise OutputError(err.path, err.problem, _KEPT) from None


def run_folder(out: Path, run_id: str) -> Path:
    """Where a run's own outputs go."""
    return out / "runs" / run_id


def check_early(out: Path, inputs: list[Path], spec: dict, force: bool) -> None:
    """ScenarioError for what Store would refuse that is known before a sweep's runs are made (a bench draws its
    tasks first, for minutes): `out` a file or holding an input; with `force`, a file simbench did not write in it;
    without, another sweep's results (a manifest whose spec is not `spec`). Store checks the rest once the runs are
    made (their fingerprint)."""
    destination.check_inputs(out, inputs)
    with destination.refused(out):
        holds = out.is_dir() and any(p.name != destination.MARKER for p in out.iterdir())
    if not holds:
        return
    if force:
        destination.check_replace(out, removes=True)
    elif _manifest_field(out / "sweep.json", "spec") != spec:
        _refuse_other_results(out)


def _refuse_other_results(out: Path) -> NoReturn:
    """ScenarioError: `out` holds other results; naming a file simbench did not write where it holds one (which
    --force would not replace either)."""
    destination.check_replace(out, removes=True)
    flag = destination.option('--force', 'force=True')
    raise ScenarioError(str(out), None, "the output folder holds other results (another sweep, or files that are not "
                                        f"a sweep's); pass {flag} to replace them, or --out to write elsewhere")


def _manifest_field(manifest: Path, key: str) -> Any:
    try:
        return json.loads(manifest.read_text()).get(key)
    except (OSError, ValueError, AttributeError):
        return None
