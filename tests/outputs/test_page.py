"""The pages (simbench.outputs.page) in a real headless browser, Debian's chromium driven over its DevTools protocol: a
run's page and a failed run's load with no console error and no request outside their folder, their images and
video load, a screenshot shows the figures where the page puts them, the report's text is escaped, the timeline
marks every event at its time; a sweep's page (the sweep's own CSV and plots) shows its tables and figures.

One short real run (spherical_arm/case1, 160x120 video at 10 fps) and one run whose physics fails are made once
for the module. Without /usr/bin/chromium (Debian: `apt-get install -y chromium`) the browser tests are skipped.
"""

import base64
import contextlib
import io
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
import yaml
from PIL import Image

import simbench
from simbench.commands.sweep import table as sweep_table
from simbench.core.errors import PhysicsError
from simbench.outputs.page import run_page, table_page, write_page
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file

CHROMIUM = Path("/usr/bin/chromium")
needs_browser = pytest.mark.skipif(not CHROMIUM.exists(),
                                   reason="needs Debian's chromium at /usr/bin/chromium: apt-get install -y chromium")
# Without the background-networking flags chromium stalls on refused connections on a machine with no network.
_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync",
          "--disable-default-apps", "--disable-extensions", "--mute-audio", "--hide-scrollbars",
          "--remote-debugging-port=0", "--remote-allow-origins=*"]
HOSTILE = 'case 1 <script>window.pwned = 1</script><img src="x" onerror="window.pwned = 2"> & "quotes"'


# --- the runs -------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def run_out(tmp_path_factory) -> Path:
    """Case 1 with a small video and a description full of markup, run once, with its page."""
    doc = yaml.safe_load(scenario_file("spherical_arm", "case1").read_text())
    doc["description"] = HOSTILE
    doc["render"] = {"width": 160, "height": 120, "fps": 10}
    out = tmp_path_factory.mktemp("page") / "case1"
    simbench.run(parse_scenario(doc, "case1.yaml", default_name="case1"), out=out)
    write_page(out, run_page(out, report(out)))
    return out


@pytest.fixture(scope="module")
def failed_out(tmp_path_factory) -> Path:
    """The PUMA's line with q3's servo 1000 times too stiff: the physics diverges (test_reliability.py)."""
    doc = yaml.safe_load(scenario_file("puma600", "line").read_text())
    doc["sim"] = {"force_limits": False, "kp": [8000, 12000, 5.0e6, 800, 800, 600]}
    out = tmp_path_factory.mktemp("page") / "stiff"
    with pytest.raises(PhysicsError):
        simbench.run(parse_scenario(doc, "stiff.yaml", default_name="stiff"), out=out)
    write_page(out, run_page(out, report(out)))
    return out


def report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())


# --- the browser ----------------------------------------------------------------------------------------------

class Browser:
    """Headless chromium and one DevTools connection to it (websockets, which mujoco depends on)."""

    def __init__(self, profile: Path):
        from websockets.sync.client import connect

        self.proc = subprocess.Popen([str(CHROMIUM), *_FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file, deadline = profile / "DevToolsActivePort", time.monotonic() + 30
        while not (port_file.exists() and len(port_file.read_text().split()) == 2):
            assert self.proc.poll() is None, "chromium exited at start"
            assert time.monotonic() < deadline, "chromium did not open its DevTools port in 30 s"
            time.sleep(0.05)
        port, path = port_file.read_text().split()
        self.stack = contextlib.ExitStack()
        self.ws = self.stack.enter_context(connect(f"ws://127.0.0.1:{port}{path}", max_size=None, open_timeout=10))
        self.ids = itertools.count(1)
        self.events: list[dict] = []  # every event received, of any session

    def _receive(self, deadline: float) -> dict:
        left = deadline - time.monotonic()
        assert left > 0, "chromium did not answer in time"
        message = json.loads(self.ws.recv(timeout=left))
        if "method" in message:
            self.events.append(message)
        return message

    def send(self, method: str, session: str | None = None, timeout: float = 20, **params) -> dict:
        """Call `method` (in `session`, or of the browser); its result."""
        call = {"id": next(self.ids), "method": method, "params": params}
        if session:
            call["sessionId"] = session
        self.ws.send(json.dumps(call))
        deadline = time.monotonic() + timeout
        while (message := self._receive(deadline)).get("id") != call["id"]:
            pass
        assert "error" not in message, f"{method}: {message['error']}"
        return message["result"]

    def wait(self, session: str, method: str, timeout: float = 30) -> None:
        """Until `session` has had an event `method`."""
        deadline = time.monotonic() + timeout
        while not any(e["method"] == method and e.get("sessionId") == session for e in self.events):
            self._receive(deadline)

    def close(self) -> None:
        self.stack.close()
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Page:
    """A page opened in a fresh tab, with what its load logged: console errors and every request."""

    def __init__(self, browser: Browser, path: Path):
        self.browser = browser
        self.target = browser.send("Target.createTarget", url="about:blank")["targetId"]
        self.session = browser.send("Target.attachToTarget", targetId=self.target, flatten=True)["sessionId"]
        for domain in ("Page", "Runtime", "Log", "Network"):
            self.call(f"{domain}.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=1200, height=900, deviceScaleFactor=1, mobile=False)
        self.call("Page.navigate", url=path.as_uri())
        browser.wait(self.session, "Page.loadEventFired")

    @property
    def events(self) -> list[dict]:
        return [e for e in self.browser.events if e.get("sessionId") == self.session]

    def call(self, method: str, **params) -> dict:
        return self.browser.send(method, self.session, **params)

    def evaluate(self, expression: str):
        """The value of a JavaScript expression (awaited if it is a promise), run by the test, not the page."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        assert "exceptionDetails" not in result, result["exceptionDetails"]
        return result["result"].get("value")

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions, failed loads and messages at error level, as the page logged them."""
        found = []
        for e in self.events:
            method, params = e.get("method"), e.get("params", {})
            if method == "Runtime.exceptionThrown":
                found.append(f"uncaught: {params['exceptionDetails'].get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                found.append(f"console.{params['type']}: {params.get('args')}")
            elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
                found.append(f"{params['entry'].get('source')}: {params['entry'].get('text')} "
                             f"{params['entry'].get('url', '')}")
            elif method == "Network.loadingFailed":
                found.append(f"failed to load: {params.get('errorText')} ({params.get('requestId')})")
        return found

    def requests(self) -> list[str]:
        return [e["params"]["request"]["url"] for e in self.events if e.get("method") == "Network.requestWillBeSent"]

    def screenshot(self, rect: dict) -> Image.Image:
        """The page's pixels in `rect` (CSS pixels of the document, scrolled or not)."""
        clip = {k: rect[k] for k in ("x", "y", "width", "height")} | {"scale": 1}
        shot = self.call("Page.captureScreenshot", format="png", clip=clip, captureBeyondViewport=True)
        return Image.open(io.BytesIO(base64.b64decode(shot["data"]))).convert("RGB")

    def close(self) -> None:
        self.browser.send("Target.closeTarget", targetId=self.target)


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.exists():
        pytest.skip("needs Debian's chromium at /usr/bin/chromium: apt-get install -y chromium")
    profile = Path(tempfile.mkdtemp(prefix="simbench-chromium-"))
    b = Browser(profile)
    yield b
    b.close()
    shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture(scope="module")
def open_page(browser):
    opened = []

    def open_(path: Path) -> Page:
        opened.append(Page(browser, path))
        return opened[-1]

    yield open_
    for page in opened:
        page.close()


# Seek the page's video to 0.55 s (its sixth frame at 10 fps) once its metadata is in; its state then.
SEEK = """new Promise(done => { const v = document.querySelector('video');
    const report = () => done({error: v.error && v.error.code, ready: v.readyState, width: v.videoWidth,
                               height: v.videoHeight, duration: v.duration});
    const seek = () => { v.addEventListener('seeked', report, {once: true}); v.currentTime = 0.55; };
    v.addEventListener('error', report);
    if (v.readyState >= 1) seek(); else v.addEventListener('loadedmetadata', seek, {once: true});
    setTimeout(report, 15000); })"""
_RECTS = """[...document.querySelectorAll('%s')].map(e => { const r = e.getBoundingClientRect();
    return {x: r.left + scrollX, y: r.top + scrollY, width: r.width, height: r.height}; })"""


def likeness(shown: Image.Image, original: Image.Image, size=(96, 72)) -> float:
    """Correlation of two pictures reduced to `size` grey pixels: about 1 for the same picture at another scale,
    near 0 for a blank box; the plots of one run, mostly white, correlate at most about 0.6 with each other."""
    a, b = (np.asarray(im.convert("L").resize(size, Image.BILINEAR), float) for im in (shown, original))
    a, b = a - a.mean(), b - b.mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum() + 1e-12))


def assert_clean_load(page: Page, folder: Path) -> None:
    """No console error, and no request but for files in `folder` and data: URLs (the browser's own icons for the
    video's controls): no network at view time."""
    assert page.errors() == []
    outside = [u for u in page.requests() if not u.startswith((folder.resolve().as_uri() + "/", "data:"))]
    assert outside == []


# --- the tests ------------------------------------------------------------------------------------------------

@needs_browser
def test_a_run_page_loads_its_plots_and_video_with_no_console_error(run_out, open_page):
    page = open_page(run_out / "index.html")
    plots = report(run_out)["outputs"]["plots"]
    images = page.evaluate("[...document.images].map(i => [i.getAttribute('src'), i.complete, i.naturalWidth, "
                           "i.naturalHeight])")
    assert [src for src, *_ in images] == plots
    for src, complete, width, height in images:
        assert complete and (width, height) == Image.open(run_out / src).size > (0, 0)
    video = page.evaluate(SEEK)
    info = report(run_out)["outputs"]["video_info"]
    assert video["error"] is None and video["ready"] >= 2  # a decoded frame at the time sought
    assert (video["width"], video["height"]) == (info["width"], info["height"]) == (160, 120)
    assert video["duration"] == pytest.approx(info["frames"] / info["fps"], abs=0.15)
    assert_clean_load(page, run_out)


@needs_browser
def test_a_screenshot_shows_each_plot_and_the_video_where_the_page_puts_them(run_out, open_page):
    page = open_page(run_out / "index.html")
    plots = report(run_out)["outputs"]["plots"]
    assert page.evaluate(SEEK)["ready"] >= 2
    rects = page.evaluate(_RECTS % "figure img")
    shots = [page.screenshot(rect) for rect in rects]
    for rel, rect, shown in zip(plots, rects, shots, strict=True):
        assert rect["width"] >= 300 and rect["height"] >= 150, rel  # shown at a readable size
        # the plot itself where the page puts it, not a blank box or another of the plots
        alike = [likeness(shown, Image.open(run_out / other)) for other in plots]
        assert alike[plots.index(rel)] > 0.95 and max(alike[:plots.index(rel)] + alike[plots.index(rel) + 1:]) < 0.8
    page.evaluate("document.querySelector('video').controls = false")  # the controls are drawn over the frame
    (rect,) = page.evaluate(_RECTS % "video")
    reader = imageio.get_reader(run_out / "video.mp4")
    sought, later = (Image.fromarray(reader.get_data(k)) for k in (5, 40))  # 0.5 to 0.6 s at 10 fps; 4 s
    reader.close()
    shown = page.screenshot(rect)
    assert likeness(shown, sought, (80, 60)) > 0.99 and likeness(shown, sought, (80, 60)) > likeness(shown, later,
                                                                                                       (80, 60))
    above = page.screenshot({**rect, "y": rect["y"] - rect["height"] - 10})
    assert likeness(above, sought, (80, 60)) < 0.5


@needs_browser
def test_text_from_the_report_shows_as_text(run_out, open_page):
    html = (run_out / "index.html").read_text()
    assert "<script" not in html and 'onerror="' not in html and "&lt;script&gt;" in html
    page = open_page(run_out / "index.html")
    assert page.evaluate("document.scripts.length") == 0 and page.evaluate("window.pwned") is None
    assert page.evaluate("document.querySelector('p.sub').textContent") == HOSTILE
    assert json.dumps(HOSTILE) in page.evaluate("document.querySelector('#config ~ details pre').textContent")
    config = page.evaluate("[...document.querySelectorAll('#config ~ .scroll tr')].map(r => [...r.cells].map(c => "
                           "c.textContent))")
    assert ["description", HOSTILE] in config
    assert page.evaluate("document.images.length") == len(report(run_out)["outputs"]["plots"])
    assert page.evaluate("document.title") == "simbench: case1: spherical_arm / safe_straight_path"
    assert_clean_load(page, run_out)


@needs_browser
def test_the_timeline_marks_every_event_at_its_time(run_out, open_page):
    rep = report(run_out)
    page = open_page(run_out / "index.html")
    events = rep["singularity_events"] + rep["limit_events"]
    assert events and rep["warnings"] == [] and rep["violations"] == []
    marks = page.evaluate("""[...document.querySelectorAll('svg.timeline g.mark')].map(g => {
        const r = g.getBoundingClientRect(); return [g.querySelector('title').textContent, r.left, r.right]; })""")
    ticks = page.evaluate("""[...document.querySelectorAll('svg.timeline text')].filter(t =>
        t.getAttribute('text-anchor') === 'middle').map(t => [Number(t.textContent),
        (t.getBoundingClientRect().left + t.getBoundingClientRect().right) / 2])""")
    (t0, x0), (t1, x1) = ticks[0], ticks[-1]

    def x(t):
        return x0 + (t - t0) * (x1 - x0) / (t1 - t0)

    assert sorted(title.split(",")[0] for title, *_ in marks) == sorted(e["kind"] for e in events)
    for e in events:
        left, right = next((lo, hi) for title, lo, hi in marks if title.startswith(e["kind"] + ","))
        assert left == pytest.approx(x(e["t_start"]), abs=2) and right == pytest.approx(x(e["t_end"]), abs=2)
    rows = page.evaluate("[...document.querySelectorAll('table.events tbody tr')].map(r => "
                         "[...r.cells].map(c => c.textContent))")
    assert {r[1]: (float(r[2]), float(r[3])) for r in rows} == {
        e["kind"]: pytest.approx((e["t_start"], e["t_end"]), rel=1e-3) for e in events}


@needs_browser
def test_the_timelines_labels_overlap_neither_each_other_nor_a_mark(tmp_path, open_page):
    """Events a few milliseconds apart in each lane, long names, and an instant at the run's end (issue 46: the
    labels were drawn over the next marks): as the browser lays them out, no label's box meets another's or a
    mark's, each lies inside the timeline, and each names a mark it starts over (or, at the end, ends over)."""
    spans = [{"t_start": t, "t_end": t + 0.02, "kind": kind, "detail": {}}
             for t, kind in ((0.9, "type2"), (0.905, "assembly_mode_change"), (0.93, "type2"), (1.2, "wrist"))]
    instants = [{"kind": kind, "t": t, "message": ""} for t, kind in
                ((0.925, "singular_crossing"), (0.9315, "assembly_mode_change"), (0.9325, "off_path"),
                 (1.3, "orientation_error"), (1.99, "goal_missed"))]
    report = {"status": "limits", "duration": 2.0, "hold": 0.0, "singularity_events": spans, "violations": instants,
              "limit_events": [{"t_start": 0.0, "t_end": 0.001, "kind": "velocity_limit_of_a_long_joint_name",
                                "detail": {}}]}
    write_page(tmp_path, run_page(tmp_path, report))
    page = open_page(tmp_path / "index.html")
    box = "r => ({x0: r.left, x1: r.right, y0: r.top, y1: r.bottom})"
    labels = page.evaluate(f"[...document.querySelectorAll('svg.timeline text.label')].map(t => "
                           f"[t.textContent, ({box})(t.getBoundingClientRect())])")
    marks = page.evaluate(f"[...document.querySelectorAll('svg.timeline g.mark')].map(g => "
                          f"[g.querySelector('title').textContent, ({box})(g.getBoundingClientRect())])")
    (frame,) = page.evaluate(f"[...document.querySelectorAll('svg.timeline')].map(s => "
                             f"({box})(s.getBoundingClientRect()))")

    def meet(a, b):
        return a["x0"] < b["x1"] and b["x0"] < a["x1"] and a["y0"] < b["y1"] and b["y0"] < a["y1"]

    assert len(marks) == 10 and len(labels) >= 5  # a label a lane at least
    for (name, a), (other, b) in itertools.combinations(labels, 2):
        assert not meet(a, b), (name, other)
    for name, a in labels:
        assert not any(meet(a, b) for _, b in marks), name
        assert frame["x0"] <= a["x0"] and a["x1"] <= frame["x1"], name
        kind, t = name.rsplit(" ", 2)[:2]
        assert any(title.startswith(f"{kind}, t = {t}") and min(abs(b["x0"] - a["x0"]), abs(b["x1"] - a["x1"])) < 8
                   for title, b in marks), name
    assert "goal_missed 1.99 s" in dict(labels)


@needs_browser
def test_a_failed_runs_page_says_when_and_why(failed_out, open_page):
    rep = report(failed_out)
    assert rep["status"] == "failed" and "plots" not in rep["outputs"] and "video" not in rep["outputs"]
    page = open_page(failed_out / "index.html")
    assert page.evaluate("document.querySelector('.status').textContent") == "failed"
    failure = page.evaluate("document.querySelector('p.failure').textContent")
    assert rep["failure"]["cause"] in failure and f"t = {rep['failure']['t']:.4g} s" in failure
    assert page.evaluate("document.images.length") == 0 and page.evaluate("document.querySelector('video')") is None
    marks = page.evaluate("[...document.querySelectorAll('g.mark title')].map(t => t.textContent)")
    assert f"failure, t = {rep['failure']['t']:.4g} s" in marks and len(marks) == 1 + len(rep["warnings"])
    assert_clean_load(page, failed_out)


def sweep_folder(out: Path) -> tuple[dict, list[str]]:
    """What a sweep writes, by its own functions (simbench.commands.sweep.table): results.csv and plots/, for six runs
    over two timesteps and three durations, one a `limits` run and one a `bad_input` row."""
    rows = []
    for k, (dt, duration) in enumerate(itertools.product([0.001, 0.002], [1, 2, 4])):
        status = "bad_input" if k == 5 else "limits" if k == 4 else "ok"
        metrics = {} if status == "bad_input" else {"tool_rms": 1e-4 / duration * (1 + dt * 100), "events": k}
        rows.append({"run": k, "id": f"r{k:03d}", "params": {"sim.timestep": dt, "timing.duration": duration},
                     "status": status, "error": "<b>off_path</b> & more" if status == "limits" else "",
                     "metrics": metrics, "wall_time": 0.5 + k})
    params = ["sim.timestep", "timing.duration"]
    columns = sweep_table.columns(rows, params)
    sweep_table.write_csv(columns, out / "results.csv")
    plots, _ = sweep_table.write_plots(columns, params, params, ["tool_rms"], out / "plots")
    return sweep_table.summary(columns, ["tool_rms"]), [f"plots/{p}" for p in plots]


@needs_browser
def test_a_sweep_page_shows_its_tables_and_figures(tmp_path, open_page):
    out = tmp_path / "sweep"
    out.mkdir()
    _, plots = sweep_folder(out)
    html = table_page(out, "spherical_arm_timestep <sweep>", "Case 1 over the timestep.\n\nSecond paragraph.",
                      [("Results", Path("results.csv"))],
                      plots, {"base": "spherical_arm/case1", "grid": {"sim.timestep": [0.001, 0.002]}})
    write_page(out, html)
    page = open_page(out / "index.html")
    assert page.evaluate("document.querySelector('h1').textContent") == "spherical_arm_timestep <sweep>"
    assert page.evaluate("document.querySelectorAll('body > p').length") == 2
    tables = page.evaluate("[...document.querySelectorAll('h3 + .scroll table')].map(t => [...t.rows].map(r => "
                           "[...r.cells].map(c => c.textContent)))")
    assert [len(t) - 1 for t in tables] == [6]
    results = tables[0]
    assert results[0] == ["run", "id", *["sim.timestep", "timing.duration"], "status", "error", "tool_rms", "events",
                          "wall_time"]
    assert results[5][5] == "<b>off_path</b> & more" and results[6][4] == "bad_input" and results[6][6] == ""
    assert float(results[1][6]) == pytest.approx(1.1e-4, rel=1e-5)
    assert page.evaluate("[...document.querySelectorAll('h3 a')].map(a => a.getAttribute('href'))") == ["results.csv"]
    images = page.evaluate("[...document.images].map(i => [i.getAttribute('src'), i.naturalWidth])")
    assert len(images) == len(plots) == 2 and all(w > 0 for _, w in images)
    for rel, rect in zip(plots, page.evaluate(_RECTS % "figure img"), strict=True):
        assert likeness(page.screenshot(rect), Image.open(out / rel)) > 0.95, rel
    assert "sim.timestep" in page.evaluate("document.querySelector('#config + .scroll').textContent")
    assert_clean_load(page, out)


def test_a_listed_output_missing_from_the_folder_is_named_not_shown(tmp_path):
    rep = {"scenario": {"name": "x"}, "robot": "r", "planner": "p", "status": "ok",
           "outputs": {"plots": ["plots/gone.png"], "video": "video.mp4"}}
    html = run_page(tmp_path, rep)
    assert "<img" not in html and "<video" not in html
    assert "Not found in this folder: plots/gone.png" in html and "Not found in this folder: video.mp4" in html


def test_a_figure_has_its_pictures_size_and_a_file_that_is_not_one_none(tmp_path):
    """Each figure's width and height are those of the array written as its PNG (a wide one spans the page); a
    file named .png that is not a picture is shown without them."""
    from simbench.outputs.page.html import figure_grid

    for name, (height, width) in {"tall.png": (301, 200), "wide.png": (90, 500)}.items():
        imageio.imwrite(tmp_path / name, np.zeros((height, width, 3), np.uint8))
    (tmp_path / "text.png").write_text("not a picture")
    html = figure_grid(tmp_path, ["tall.png", "wide.png", "text.png"])
    assert '<figure><img src="tall.png" alt="tall" width="200" height="301">' in html
    assert '<figure class="wide"><img src="wide.png" alt="wide" width="500" height="90">' in html
    assert '<img src="text.png" alt="text">' in html


def test_a_figure_outside_the_folder_is_refused(tmp_path):
    """A page refers to its pictures by paths inside its folder, so that it moves with the folder."""
    for path in ("/etc/hostname", "../elsewhere.png", "plots/../../elsewhere.png"):
        with pytest.raises(ValueError, match="inside it"):
            table_page(tmp_path, "t", "", [], [path])
        with pytest.raises(ValueError, match="inside it"):
            run_page(tmp_path, {"outputs": {"plots": [], "video": path}})


def test_write_page_writes_index_html_in_one_step(tmp_path):
    path = write_page(tmp_path, table_page(tmp_path, "t \u00b0", "", [], [], None))
    assert path == tmp_path / "index.html" and sorted(os.listdir(tmp_path)) == ["index.html"]
    assert path.read_bytes().isascii() and "t &#176;" in path.read_text()
