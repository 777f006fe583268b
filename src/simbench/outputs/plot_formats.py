"""The file formats simbench writes plots in (`--plot-format`, `plot_format=`): PNG for the result page and the
screen, SVG and PDF for papers; and those it exports a run's timeseries in (`simbench export`, `--timeseries`). Kept
apart from the writers, so that the command line names them without importing NumPy and MuJoCo."""

from __future__ import annotations

from simbench.core.errors import ScenarioError

FORMATS = ("png", "svg", "pdf")
TIMESERIES_FORMATS = ("csv",)


def check_format(plot_format: str, source: str) -> None:
    """ScenarioError (bad input, naming `source`) unless `plot_format` is one simbench writes."""
    if plot_format not in FORMATS:
        raise ScenarioError(source, "plot_format", f"expected one of {', '.join(FORMATS)}, got {plot_format!r:.40}")
