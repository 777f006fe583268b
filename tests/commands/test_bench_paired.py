"""Paired statistics between methods, a Pareto plot per arm and the all-arms page (issue 47). Truths: paired.csv
recounted from runs.csv as the csv module reads it back (wins, ties and losses counted here, the median paired
difference and its percentile bootstrap interval re-derived with NumPy from the generator's stated recipe), the
Pareto front by its definition written as loops, PNG files as Pillow reads them, and the pages' links as an HTML
parser reads them, resolved against the folder. Synthetic runs for the arithmetic; one tiny real bench (2 arms,
2 tasks, 2 methods) end to end."""

import csv
import itertools
import json
import math
import zlib
from contextlib import nullcontext
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from simbench.commands.bench import board, load_suite, outputs, run_bench
from simbench.core import destination

SEED = 7


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _number(text):
    return None if text == "" else float(text)


# --- the recomputation from runs.csv ------------------------------------------------------------------------------

def _outcome_ok(a, b):
    return (a["status"] == "ok") - (b["status"] == "ok")


def _outcome_deviation(a, b):
    """+1 where A's deviation is the smaller to 6 significant digits, 0 equal there or both missing, a missing one
    losing to one present."""
    x, y = (_number(r["deviation_max_mm"]) for r in (a, b))
    x, y = (None if v is None or not math.isfinite(v) else float(f"{v:.6g}") for v in (x, y))
    if x is None and y is None:
        return 0
    if x is None or y is None:
        return 1 if y is None else -1
    return 0 if x == y else (1 if x < y else -1)


def _differences(pairs, column):
    out = []
    for a, b in pairs:
        x, y = _number(a[column]), _number(b[column])
        if x is not None and y is not None and math.isfinite(x) and math.isfinite(y):
            out.append(x - y)
    return out


def _expected(runs_rows, seed):
    """paired.csv's rows, in its order, recomputed from runs.csv's rows (as the csv module reads them)."""
    expected = []
    for robot in dict.fromkeys(r["robot"] for r in runs_rows):
        mine = [r for r in runs_rows if r["robot"] == robot]
        for a, b in itertools.combinations(dict.fromkeys(r["method"] for r in mine), 2):
            bs = {r["task"]: r for r in mine if r["method"] == b}
            pairs = [(r, bs[r["task"]]) for r in mine if r["method"] == a and r["task"] in bs]
            row = {"robot": robot, "method_a": a, "method_b": b, "tasks": len(pairs)}
            defined = {name: mine[0][name] for name in ("version", "seed", "model_hash")}  # runs.csv's, to the end
            for name, outcome in (("ok", _outcome_ok), ("deviation", _outcome_deviation)):
                outcomes = [outcome(x, y) for x, y in pairs]
                row.update({f"{name}_wins": outcomes.count(1), f"{name}_ties": outcomes.count(0),
                            f"{name}_losses": outcomes.count(-1)})
            rng = np.random.default_rng([seed, zlib.crc32(robot.encode()), zlib.crc32(a.encode()),
                                         zlib.crc32(b.encode())])
            for name, column in (("deviation", "deviation_max_mm"), ("slowdown", "slowdown")):
                d = np.array(_differences(pairs, column))
                row[f"{name}_n"] = len(d)
                median = f"{name}_diff_median" + ("_mm" if name == "deviation" else "")
                if len(d):  # the generator draws for the deviation first, then for the slowdown
                    medians = np.median(d[rng.integers(0, len(d), (2000, len(d)))], axis=1)
                    row[median], (row[f"{median}_lo"], row[f"{median}_hi"]) = (
                        float(np.median(d)), np.percentile(medians, [2.5, 97.5]))
                else:
                    row[median] = row[f"{median}_lo"] = row[f"{median}_hi"] = None
            expected.append({**row, **defined})
    return expected


def _check_paired(folder, seed):
    """paired.csv in `folder` against the recomputation from its runs.csv; the rows checked."""
    written, expected = _read(folder / "paired.csv"), _expected(_read(folder / "runs.csv"), seed)
    assert [(r["robot"], r["method_a"], r["method_b"]) for r in written] == [
        (r["robot"], r["method_a"], r["method_b"]) for r in expected]
    for ours, truth in zip(written, expected):
        assert set(ours) == set(truth)
        for name, value in truth.items():
            if isinstance(value, str):
                assert ours[name] == value
            elif isinstance(value, int):
                assert int(ours[name]) == value, name
            elif value is None:
                assert ours[name] == "", name
            else:
                assert float(ours[name]) == pytest.approx(float(value), rel=1e-5, abs=1e-12), (truth, name)
        for median in ("deviation_diff_median_mm", "slowdown_diff_median"):
            if ours[median]:
                assert float(ours[f"{median}_lo"]) <= float(ours[median]) <= float(ours[f"{median}_hi"])
        assert int(ours["ok_wins"]) + int(ours["ok_ties"]) + int(ours["ok_losses"]) == int(ours["tasks"])
    return written


# --- synthetic runs -----------------------------------------------------------------------------------------------

def _synthetic(seed=3):
    """runs.csv's columns for two arms: three methods on r1 (c skipping a task), two on r2; statuses, deviations
    (some missing, some equal to 6 digits but not to the bit, one infinite) and slowdowns drawn at `seed`."""
    rng = np.random.default_rng(seed)
    runs = {name: [] for name in (*board.PARAMS, "scenario", *board.COLUMNS, "violations", "wall_time")}
    for robot, methods in (("r1", ("a", "b", "c")), ("r2", ("b", "a"))):
        for t in range(12):
            task = f"{robot}-t{t:04d}"
            base = float(rng.lognormal(0, 1))
            for m in methods:
                if (m, t) == ("c", 5):
                    continue
                deviation = base * (1 + float(rng.choice([0, 1e-9, 1e-3, 0.5])))
                if rng.random() < 0.15:
                    deviation = None
                if (robot, m, t) == ("r1", "b", 7):
                    deviation = math.inf
                slowdown = float(rng.choice([1.0, 1.0, 1.5, 3.2])) if rng.random() > 0.1 else None
                row = {"robot": robot, "task": task, "kind": ("through", "near", "far")[t % 3], "shape": "line",
                       "method": m, "planner": "cartesian_path", "anchor_gap": 0.1, "length_mm": 100.0,
                       "duration": 2.0, "scenario": board.scenario_file(f"{task}-{m}"),
                       "status": str(rng.choice(["ok", "ok", "limits", "too_slow", "run_failed"])), "error": "",
                       "deviation_max_mm": deviation, "orientation_max_deg": 0.1, "speed_share_max": 0.8,
                       "slowdown": slowdown, "closest_approach": 0.05, "violations": "", "wall_time": 1.0}
                for name, value in row.items():
                    runs[name].append(value)
    return runs


class _Store:
    """What outputs.write asks of a bench's folder store: claims recorded, writes as they are."""

    def __init__(self, out):
        self.out, self.claimed = out, []
        destination.mark(out, [])

    def claim(self, names):
        self.claimed += names
        destination.mark_more(self.out, names)

    def writing(self):
        return nullcontext()


def _write(out, runs, robots=None):
    out.mkdir()
    summary = {"suite": "synthetic", "version": "sb-1", "seed": SEED, "tasks": 12, "methods": ["a", "b", "c"],
               "robots": robots or list(dict.fromkeys(runs["robot"])),
               "runs": len(runs["task"]), "status": {"ok": 1}, "backend": "here", "max_slowdown": 10.0,
               "plan_seconds": 120.0, "models": {robot: f"hash-of-{robot}" for robot in runs["robot"]}}
    boards = (board.leaderboard(runs, SEED), board.leaderboard(runs, SEED, ("robot", "method", "kind")))
    outputs.write(_Store(out), out, runs, boards, summary, 1)
    return out


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    return _write(tmp_path_factory.mktemp("paired") / "one", _synthetic())


def test_paired_csv_is_runs_csv_recounted(synthetic):
    rows = _check_paired(synthetic, SEED)
    assert [(r["robot"], r["method_a"], r["method_b"]) for r in rows] == [
        ("r1", "a", "b"), ("r1", "a", "c"), ("r1", "b", "c"), ("r2", "b", "a")]
    assert [int(r["tasks"]) for r in rows] == [12, 11, 11, 12]
    assert any(int(r["deviation_ties"]) for r in rows) and any(int(r["deviation_wins"]) for r in rows)
    assert all(int(r["deviation_n"]) < int(r["tasks"]) for r in rows)  # missing and infinite values left out


def test_the_same_runs_write_the_same_bytes(synthetic, tmp_path):
    again = _write(tmp_path / "again", _synthetic())
    for name in ("paired.csv", "index.html", "arm-r1.html", "arm-r2.html", "plots/pareto_r1.png"):
        assert (again / name).read_bytes() == (synthetic / name).read_bytes(), name


def test_an_arm_no_method_applied_to_has_its_row_and_page(tmp_path):
    """A suite's arm without a run (no method of the suite applies to it): its row in the all-arms grid says
    `not run` for every method and links its page, which exists, as does every link on it."""
    out = _write(tmp_path / "idle", _synthetic(), ["r1", "r2", "r3"])
    page = _Page(out / "index.html")
    rows = {row[0]["text"]: row for row in page.grid[1:]}
    assert list(rows) == ["r1", "r2", "r3"]
    assert [cell["text"] for cell in rows["r3"][1:]] == ["not run"] * 3
    assert rows["r3"][0]["href"] == "arm-r3.html" and json.loads((out / "summary.json").read_text())["outputs"][
        "arm_pages"] == ["arm-r1.html", "arm-r2.html", "arm-r3.html"]
    assert _resolves(out, rows["r3"][0]["href"])
    assert all(_resolves(out, link) for link in _Page(out / "arm-r3.html").links)


def test_the_pareto_front_is_the_points_no_other_dominates():
    rng = np.random.default_rng(1)
    points = np.vstack([rng.integers(0, 6, (40, 2)), [[0, 5], [0, 5]]]).astype(float)
    front = outputs.non_dominated(points)
    for i, p in enumerate(points):
        beaten = any(all(q <= p) and any(q < p) for q in points)
        assert front[i] == (not beaten)


# --- one real bench -----------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """planar3r and spherical_arm, 2 tasks each, by dls_adaptive and pinv, at SEED."""
    folder = tmp_path_factory.mktemp("arms")
    (folder / "suite.yaml").write_text(f"name: two_arms\ntasks: 2\nseed: {SEED}\nmethods: [dls_adaptive, pinv]\n"
                                       "robots: [planar3r, spherical_arm]\n")
    return run_bench(load_suite(folder / "suite.yaml"), folder / "out", workers=1).out


class _Page(HTMLParser):
    """A page's links and ids, and the rows of the table after the heading with id `arms`."""

    def __init__(self, path):
        super().__init__()
        self.links, self.ids, self.grid, self._in_grid, self._cell = [], set(), [], False, None
        self.feed(Path(path).read_text())

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
            self._in_grid = attrs["id"] == "arms"
        if tag in ("a", "img"):
            self.links.append(attrs.get("href") or attrs.get("src"))
        if self._in_grid and tag == "tr":
            self.grid.append([])
        if self._in_grid and tag in ("td", "th"):
            self._cell = {"text": "", "href": None}
            self.grid[-1].append(self._cell)
        if self._cell is not None and tag == "a":
            self._cell["href"] = attrs["href"]

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self._cell = None
        if tag == "table":
            self._in_grid = False

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data


def _resolves(folder, link):
    path, _, anchor = link.partition("#")
    target = folder / path
    return target.is_file() and (not anchor or anchor in _Page(target).ids)


def test_a_real_bench_writes_paired_csv_as_its_runs_recount(bench):
    rows = _check_paired(bench, SEED)
    assert [(r["robot"], int(r["tasks"])) for r in rows] == [("planar3r", 2), ("spherical_arm", 2)]


def test_a_pareto_plot_per_arm_is_a_png(bench):
    for robot in ("planar3r", "spherical_arm"):
        path = bench / "plots" / f"pareto_{robot}.png"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        with Image.open(path) as picture:
            picture.verify()
        with Image.open(path) as picture:
            assert picture.format == "PNG" and min(picture.size) > 100


def test_the_all_arms_grid_links_each_cell_to_its_arms_page(bench):
    """A row per arm, a cell per method showing its ok share and deviation p95 from leaderboard.csv, each linking
    the arm's page, which holds that arm's Pareto plot and whose every link resolves in the folder."""
    page = _Page(bench / "index.html")
    header, *rows = page.grid
    assert [c["text"] for c in header] == ["arm", "dls_adaptive", "pinv"]
    board_rows = {(r["robot"], r["method"]): r for r in _read(bench / "leaderboard.csv")}
    assert [row[0]["text"] for row in rows] == ["planar3r", "spherical_arm"]
    for row in rows:
        robot = row[0]["text"]
        for method, cell in zip(("dls_adaptive", "pinv"), row[1:]):
            assert cell["href"] == row[0]["href"] and _resolves(bench, cell["href"])
            ok, deviation = cell["text"].removesuffix(" mm").split(" / ")
            assert float(ok) == pytest.approx(float(board_rows[robot, method]["ok_share"]), rel=5e-3)
            assert float(deviation) == pytest.approx(float(board_rows[robot, method]["deviation_p95_mm"]), rel=5e-3)
        arm = _Page(bench / row[0]["href"])
        assert f"plots/pareto_{robot}.png" in arm.links and "index.html" in arm.links
        assert not any("pareto" in link and robot not in link for link in arm.links)
        assert all(_resolves(bench, link) for link in arm.links)
    assert all(_resolves(bench, link) for link in page.links)


def test_every_file_the_bench_wrote_is_claimed(bench):
    assert destination.foreign(bench, empty=True) == []
