"""What a new user's first hour found in the plots, the run's page and the docs site (issue 46): the 3-D path on
equal axes, tick labels without an offset, event names in the singularity plot that do not overlap, the run's
page (record_every among the run's settings, closest_approach where the robot lacks its measure), and the site's
tables, API headings and sidebar at 1280 px."""

import dataclasses
import os
import re
from itertools import combinations

import numpy as np
import pytest
import yaml

import simbench
from simbench.api import Event
from simbench.commands.pipeline import thinned
from simbench.outputs import plots
from simbench.outputs.page import run_page
from simbench.outputs.report import build_report
from simbench.scenario import load_scenario, parse_scenario
from tests.conftest import scenario_file
from tests.outputs.test_page import Page, browser  # noqa: F401  (headless chromium: getfixturevalue)
from tests.project.test_docs import site  # noqa: F401  (the docs site, built once by test_docs: getfixturevalue)


def evaluated(scenario):
    """The scenario, its evaluation, and its plan and recording at the kept rows (what the plots draw)."""
    ev = simbench.evaluate(scenario)
    return scenario, ev, *thinned(ev.trajectory, ev.recording)


@pytest.fixture(scope="module")
def demo():
    return evaluated(load_scenario(scenario_file("spherical_arm", "demo")))


@pytest.fixture(scope="module")
def one_joint_moving(tmp_path_factory):
    """The planar 3R derived from its MJCF, q1 alone moving: its singularity measures (which q1 leaves alone) are
    constant but for the servos' wobble, 1e-9 to 1e-5 of their values: where matplotlib wrote `1e-5+1.851e-1`."""
    planar3r = pytest.importorskip("simbench_planar3r", reason="pip install -e examples/planar3r")
    scene = os.path.join(os.path.dirname(planar3r.__file__), "models", "scene.xml")
    doc = {"robot": {"model": scene, "tool": {"site": "tool"}, "speed_limits": [180, 360, 360]},
           "planner": "joint_move", "units": {"angle": "deg", "length": "mm"},
           "task": {"start": [7.65, -90, -60], "goal": [60, -90, -60]},
           "timing": {"law": "quintic", "duration": 2.0, "hold": 0.3}}
    folder = tmp_path_factory.mktemp("held")
    return evaluated(parse_scenario(doc, str(folder / "held.yaml"), default_name="held"))


def drawn(run, folder):
    """Every plot of the run, saved as simbench saves them (plots.save), by stem."""
    scenario, ev, traj, rec = run
    figures = plots.draw_plots(scenario.robot_def, traj, rec, ev.analysis)
    for stem, fig in figures.items():
        plots.save(fig, folder, stem)
    return figures


def axes_of(fig):
    for ax in fig.axes:
        yield from (axis for axis in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None)) if axis is not None)


# --- plots ----------------------------------------------------------------------------------------------------

def test_the_path_is_drawn_on_equal_axes(demo, tmp_path):
    """The demo's line spans 544 mm in x, 0.1 mm in y: each axis as long as the others, in a cubic box, and the
    path inside; matplotlib's own limits had stretched y's 0.1 mm over the box's width."""
    ax = drawn(demo, tmp_path)["path"].axes[0]
    spans = [np.ptp(limits) for limits in (ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d())]
    assert spans == pytest.approx([spans[0]] * 3, rel=1e-9)
    box = ax.get_box_aspect()
    assert box == pytest.approx([box[0]] * 3, rel=1e-9)  # so a millimetre is as long on each axis
    points = demo[2].tool_ref * 1e3
    for k, limits in enumerate((ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d())):
        assert limits[0] <= points[:, k].min() and points[:, k].max() <= limits[1]
    assert spans[0] == pytest.approx(np.ptp(points, axis=0).max(), rel=0.01)  # no wider than the path


@pytest.mark.parametrize("name", ["demo", "one_joint_moving"])
def test_no_axis_of_a_plot_has_an_offset_and_its_labels_stay_short(name, request, tmp_path):
    """Every axis of every plot (the 3-D one's z too): no offset added to its tick labels, and labels of at most
    9 characters (a nearly constant series widened to MIN_SPAN of its size), which leave room for the y label."""
    for stem, fig in drawn(request.getfixturevalue(name), tmp_path).items():
        for axis in axes_of(fig):
            formatter = axis.get_major_formatter()
            assert formatter.offset == 0 and "+" not in formatter.get_offset(), (stem, formatter.get_offset())
            longest = max((len(t.get_text()) for t in axis.get_ticklabels() if t.get_visible()), default=0)
            assert longest <= 9, (stem, [t.get_text() for t in axis.get_ticklabels()])


def label_boxes(fig):
    """The singularity plot's event names as drawn (Agg), and the top panel's frame."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    ax = fig.axes[0]
    return {t.get_text(): t.get_window_extent(renderer) for t in ax.texts}, ax.get_window_extent(renderer)


def test_event_names_in_the_singularity_plot_do_not_overlap(demo):
    """Five kinds of events within 30 ms (names side by side would overlap; the plot drew them on top of one
    another) and one ending the run: each named inside the panel, no two names overlapping, or counted in the
    title as unlabelled."""
    scenario, ev, _, rec = demo
    kinds = ["cos_q3_zero", "workspace_boundary", "lift_axis", "wrist_flip", "elbow", "at_the_end"]
    times = [2.70, 2.705, 2.71, 2.72, 2.73, 5.45]
    events = [Event(t, t + 0.01, kind) for kind, t in zip(kinds, times)]
    analysis = dataclasses.replace(ev.analysis, singularity_events=events)
    fig = plots.plot_singularity(scenario.robot_def, rec, analysis)
    boxes, frame = label_boxes(fig)
    for (a, box), (b, other) in combinations(boxes.items(), 2):
        assert not box.overlaps(other), (a, b)
    for name, box in boxes.items():
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1 and frame.y0 <= box.y0 and box.y1 <= frame.y1, name
    title = fig.axes[0].get_title()
    left_out = int(re.search(r"(\d+) unlabelled", title).group(1)) if "unlabelled" in title else 0
    assert set(boxes) <= set(kinds) and len(boxes) + left_out == len(kinds) and len(boxes) >= 4
    assert "at_the_end" in boxes  # named to the left of its time, at the panel's right edge


def test_the_agile_eyes_type2_and_assembly_mode_change_are_both_named_apart():
    """A shipped run with two kinds of events 24 ms apart."""
    scenario, ev, _, rec = evaluated(load_scenario(scenario_file("agile_eye", "through_singularity")))
    boxes, _ = label_boxes(plots.plot_singularity(scenario.robot_def, rec, ev.analysis))
    assert set(boxes) == {"type2", "assembly_mode_change"}
    assert not boxes["type2"].overlaps(boxes["assembly_mode_change"])


# --- the run's page -------------------------------------------------------------------------------------------

def test_record_every_is_a_setting_of_the_run_not_a_figure_of_the_robot(tmp_path):
    """In the Run table beside the timestep (it was in none but the configuration's), and not among the robot's
    own figures (a figure of the robot's added so that the page has that table)."""
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    doc["sim"] = {"record_every": 4}
    scenario, ev, *_ = evaluated(parse_scenario(doc, "case1.yaml", default_name="case1"))
    report = build_report(scenario, ev, {}, {}, scenario.source)
    html = run_page(tmp_path, {**report, "closure_error_max": 1e-5})
    run = html[html.index('<h2 id="run">'):html.index('<h2 id="config">')]
    assert '<tr><td>timestep (s)</td><td class="n">0.001</td></tr>' in run
    assert '<tr><td>record_every</td><td class="n">4</td></tr>' in run
    own = re.search(r"The robot&#x27;s own figures</caption>(.*?)</table>", html, re.DOTALL).group(1)
    assert "closure_error_max" in own and "record_every" not in own


def test_closest_approach_shows_the_closest_singular_event_where_the_robot_lacks_the_measure(demo, tmp_path):
    """The spherical arm measures no sigma_min_unit (report.json's closest_approach: null) but meets its lift axis:
    the page names that event's closest sample, its gap and time as report.json gives them."""
    scenario, ev, *_ = demo
    report = build_report(scenario, ev, {}, {}, scenario.source)
    assert report["metrics"]["singularity_handling"]["closest_approach"] is None
    (event,) = report["singularity_events"]
    (gap,) = event["detail"]["gaps_at_closest"].items()
    html = run_page(tmp_path, report)
    cell = re.search(r"<td>closest_approach</td><td[^>]*>(.*?)</td>", html).group(1)
    assert cell == (f"n/a (no sigma_min_unit); closest event: {event['kind']} at "
                    f"{event['detail']['t_closest']:.4g} s, {gap[0]} {gap[1]:.4g}")
    report["singularity_events"] = []
    assert "<td>closest_approach</td><td>n/a</td>" in run_page(tmp_path, report)
    report["metrics"]["singularity_handling"]["closest_approach"] = 0.0149
    assert '<td>closest_approach</td><td class="n">0.0149</td>' in run_page(tmp_path, report)


# --- the docs site --------------------------------------------------------------------------------------------

def built(request):
    out, done = request.getfixturevalue("site")
    assert done.returncode == 0, done.stdout + done.stderr
    return out


def test_no_heading_or_sidebar_entry_of_the_api_reference_is_an_empty_box_or_a_stray_module(request):
    """mkdocstrings' symbol-type badges are empty <code> elements that only the material theme fills (readthedocs
    drew them as empty boxes), and a page's module shown without its heading (api.md) still had a sidebar entry,
    `api`."""
    out = built(request)
    for page in sorted(out.rglob("index.html")):
        text = page.read_text(encoding="utf-8")
        assert not re.search(r"<code[^>]*></code>", text), page.relative_to(out)
    api = (out / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    assert not re.search(r'href="#simbench\.api">', api)
    assert re.search(r'href="#simbench\.api\.Robot">\s*Robot</a>', api)


def test_no_table_of_the_site_scrolls_sideways_at_1280_px(request):
    """The readthedocs theme kept each cell on one line: the home page's table of robots (1448 px in a 696 px
    column), and 19 more tables in 11 more pages, scrolled sideways."""
    out, chromium = built(request), request.getfixturevalue("browser")
    wide = {}
    for path in sorted(p for p in out.rglob("index.html") if "<table" in p.read_text(encoding="utf-8")):
        page = Page(chromium, path)
        page.call("Emulation.setDeviceMetricsOverride", width=1280, height=900, deviceScaleFactor=1, mobile=False)
        found = page.evaluate("""[...document.querySelectorAll('[role=main] table')].filter(t =>
            t.scrollWidth > t.clientWidth + 1).map(t => t.innerText.slice(0, 30))""")
        if found:
            wide[str(path.relative_to(out))] = found
        page.close()
    assert wide == {}
