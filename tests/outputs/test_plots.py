"""The plots as a user gets them (issue 34): the demo's in each format simbench writes (PNG for the page, SVG and
PDF for papers), each checked by what the format itself requires; a robot's own plots drawn on real matplotlib
Axes; and every file report.json lists written."""

import json
import re
from xml.etree import ElementTree

import pytest
from PIL import Image

import simbench
from simbench.api import registry
from simbench.cli import main
from simbench.core.errors import ScenarioError
from tests.conftest import scenario_file

STEMS = ["joints", "joint_speeds", "tool_deviation", "singularity", "path"]
FORMATS = ["png", "svg", "pdf"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The demo, without its video, once in each plot format: {format: output folder}."""
    folders = {}
    for plot_format in FORMATS:
        out = tmp_path_factory.mktemp(plot_format) / "demo"
        simbench.run(scenario_file("spherical_arm", "demo"), out=out, video=False, plot_format=plot_format)
        folders[plot_format] = out
    return folders


def listed(outputs: dict) -> list[str]:
    """Every file name in report.json's outputs (video_info describes the video: no file)."""
    names = []
    for key, value in outputs.items():
        if key != "video_info":
            names += value if isinstance(value, list) else [value]
    return names


@pytest.mark.parametrize("plot_format", FORMATS)
def test_the_report_lists_each_plot_with_its_format_and_every_listed_file_exists(runs, plot_format):
    out = runs[plot_format]
    outputs = json.loads((out / "report.json").read_text())["outputs"]
    assert outputs["plots"] == [f"plots/{stem}.{plot_format}" for stem in STEMS]
    assert all((out / name).is_file() for name in listed(outputs))
    assert sorted(p.name for p in (out / "plots").iterdir()) == sorted(f"{s}.{plot_format}" for s in STEMS)


def test_the_pngs_decode_and_show_something(runs):
    for stem in STEMS:
        with Image.open(runs["png"] / "plots" / f"{stem}.png") as image:
            assert image.format == "PNG"
            image.load()  # decodes every row: a truncated or corrupt file raises
            assert image.width > 500 and image.height > 300
            lo, hi = image.convert("L").getextrema()
            assert lo < 80 and hi > 240  # dark lines and text on a light background


def test_the_svgs_are_svg_documents_with_drawing_in_them(runs):
    for stem in STEMS:
        root = ElementTree.parse(runs["svg"] / "plots" / f"{stem}.svg").getroot()
        assert root.tag == "{http://www.w3.org/2000/svg}svg"
        assert len(root.findall(".//{http://www.w3.org/2000/svg}path")) > 20


def test_the_pdfs_are_whole_pdf_files(runs):
    """Header and end-of-file marker, and the cross-reference table where `startxref` says it is (what a reader
    looks for first); with pypdf installed, also one page read by it."""
    for stem in STEMS:
        data = (runs["pdf"] / "plots" / f"{stem}.pdf").read_bytes()
        assert data.startswith(b"%PDF-") and data.rstrip().endswith(b"%%EOF")
        offset = int(re.search(rb"startxref\s+(\d+)\s+%%EOF\s*$", data).group(1))
        assert data[offset:offset + 4] == b"xref"
        assert b"trailer" in data[offset:] and b"/Root" in data[offset:]
        try:
            from pypdf import PdfReader
        except ImportError:
            continue
        assert len(PdfReader(runs["pdf"] / "plots" / f"{stem}.pdf").pages) == 1


def test_the_page_shows_svg_plots_and_links_pdf_ones(runs):
    svg_page = (runs["svg"] / "index.html").read_text()
    pdf_page = (runs["pdf"] / "index.html").read_text()
    for stem in STEMS:
        assert f'<img src="plots/{stem}.svg"' in svg_page
        assert f'<a href="plots/{stem}.pdf">' in pdf_page and f'<img src="plots/{stem}.pdf"' not in pdf_page


def band_plot(self, traj, rec, analysis):
    """A robot's own plot through calls simbench's imitation Axes lacked: fill_between, set_xlim, text."""
    from simbench.api.panels import time_panels

    fig, axes = time_panels(1, 6, 3)
    ax = axes[0, 0]
    ax.fill_between(rec.t, rec.q[:, 1] - 0.01, rec.q[:, 1] + 0.01, color="tab:green", alpha=0.4)
    ax.set_xlim(1.0, 2.0)
    ax.text(1.5, 0.5, "mid-run band", transform=ax.get_xaxis_transform())
    return {"band": fig}


def test_a_robots_plots_hook_draws_on_matplotlib_axes(tmp_path, monkeypatch):
    arm = type(registry.robots()["spherical_arm"])
    monkeypatch.setattr(arm, "plots", band_plot)
    out = tmp_path / "demo"
    result = simbench.run(scenario_file("spherical_arm", "demo"), out=out, video=False, plot_format="svg")
    assert result.report["outputs"]["plots"] == [*(f"plots/{s}.svg" for s in STEMS), "plots/band.svg"]
    svg = (out / "plots" / "band.svg").read_text()
    assert ElementTree.fromstring(svg).get("viewBox").split() == ["0", "0", "432", "216"]  # 6 x 3 in, in points
    # matplotlib writes each text's string in a comment beside its glyphs: the text, and ticks of the 1-2 s view
    assert "<!-- mid-run band -->" in svg and "<!-- 1.2 -->" in svg and "<!-- 4 -->" not in svg


def test_an_error_in_a_robots_plots_hook_fails_the_run_with_that_error(tmp_path, monkeypatch):
    def broken(self, traj, rec, analysis):
        raise ValueError("no such panel")

    monkeypatch.setattr(type(registry.robots()["spherical_arm"]), "plots", broken)
    with pytest.raises(ValueError, match="no such panel"):
        simbench.run(scenario_file("spherical_arm", "demo"), out=tmp_path / "demo", video=False)
    assert not (tmp_path / "demo").exists()


def test_the_command_line_takes_a_plot_format_and_refuses_others(tmp_path, capsys):
    out = tmp_path / "case1"
    assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video", "--quiet",
                 "--plot-format", "pdf"]) == 0
    assert all(name.endswith(".pdf") for name in json.loads((out / "report.json").read_text())["outputs"]["plots"])
    with pytest.raises(SystemExit) as exit_:
        main(["run", str(scenario_file("spherical_arm", "case1")), "--plot-format", "jpg"])
    assert exit_.value.code == 2 and "invalid choice: 'jpg'" in capsys.readouterr().err
    with pytest.raises(ScenarioError, match="plot_format: expected one of png, svg, pdf, got 'jpg'"):
        simbench.run(scenario_file("spherical_arm", "case1"), out=tmp_path / "jpg", video=False, plot_format="jpg")


def test_an_exit_or_an_unpicklable_error_from_a_plots_hook_is_one_line_and_exit_1(tmp_path, monkeypatch, capsys):
    """What a hook raises in the process drawing the plots reaches the command as the run's own code would: an
    exit is outside code's failure (exit 1, one line), and an error that cannot cross back between processes is
    named."""
    arm = type(registry.robots()["spherical_arm"])

    class Odd(Exception):  # a local class: not picklable
        pass

    for raised, said in ((SystemExit(3), "outside code simbench called raised SystemExit: 3"),
                         (Odd("lost"), "drawing the plots raised Odd: lost")):
        def hook(self, traj, rec, analysis, raised=raised):
            raise raised

        monkeypatch.setattr(arm, "plots", hook)
        out = tmp_path / type(raised).__name__
        assert main(["run", str(scenario_file("spherical_arm", "case1")), "--out", str(out), "--no-video",
                     "--quiet"]) == 1
        assert said in capsys.readouterr().err and not out.exists()


def test_a_sweeps_worker_draws_each_runs_plots_too(tmp_path):
    """A sweep that keeps every run's outputs runs them in worker processes, which fork the plots' process in
    turn: each run's plots are written and listed."""
    sweep = tmp_path / "full.yaml"
    sweep.write_text(f"name: full\nbase: {scenario_file('spherical_arm', 'case1')}\noutputs: full\n"
                     "grid: {timing.duration: [2, 3]}\n")
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--workers", "2", "--quiet"]) == 0
    reports = sorted((tmp_path / "out" / "runs").glob("*/report.json"))
    assert len(reports) == 2
    for report in reports:
        outputs = json.loads(report.read_text())["outputs"]
        assert outputs["plots"] == [f"plots/{stem}.png" for stem in STEMS]
        assert all((report.parent / name).is_file() for name in listed(outputs))
