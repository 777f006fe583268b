"""simbench.commands.reproduce: every paper regenerated beside its printed values, every difference classified (issue
15).

Paper 000's Table 2 is checked against truths that do not come from the planner: the arm's forward kinematics
(a printed row, corrected as classified, must put the tool at its own printed x, y, z) and the geometry of
Fig. 8's triangle. The files are read back as a user's tools would: CSV by the csv module, Markdown tables by
their rows, PNGs decoded by Pillow.
"""

import csv
import json

import numpy as np
import pytest
from PIL import Image

from simbench.commands.reproduce import CLASSES, ERROR, OURS, PAPERS, TYPO, paper000, reproduce
from simbench.commands.reproduce._common import PIXELS
from simbench.core.errors import ScenarioError
from simbench.robots.spherical_arm import D4, fk

CELLS = paper000.compare()
TABLE2 = {case.name: case for case in paper000.PRINTED}

# Paper 000's Errata: the printed values that differ from the method, and the class of each.
EXPECTED_DIFFERING = {
    **{("case 1", "path", r, "q4"): TYPO for r in (7, 8)},  # rows 7 and 8 have their q4 swapped
    **{("case 4", "path", 2, c): TYPO for c in ("q1", "q3")},  # row 2: q1 304.3462, q3 24.8714
    **{("case 3", b, r, "q1"): ERROR for b in ("path", "attempt") for r in range(1, 12)},  # printed 350, x, y say 120
    **{("case 3", "attempt", r, "q3"): ERROR for r in (2, 3)},  # forward q3 with backward q1
    **{("case 4", "new q3", 1, c): ERROR for c in ("q3)new", "q3_init new")},  # Fig. 8's triangle is infeasible
}


def si(q):
    return np.array([np.deg2rad(q[0]), q[1] / 1e3, np.deg2rad(q[2]), q[3] / 1e3])


def fk_mm(q_deg_mm):
    return fk(si(q_deg_mm))[0] * 1e3


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    return out, reproduce("all", out)


def test_table2_44_rows_reproduced_except_exactly_the_classified_values():
    rows = paper000.rows_reproduced(CELLS)
    assert rows == {"rows": 44, "as_printed": 30, "reproduced": 44, "unexplained": 0}
    differing = {(c.case, c.block, c.row, c.column): c.status for c in CELLS if not c.agrees}
    assert differing == EXPECTED_DIFFERING
    for c in CELLS:  # every agreeing value within half a unit of its last printed digit
        if c.agrees and c.printed != "none":
            decimals = len(c.printed.split(".")[1]) if "." in c.printed else 0
            assert abs(c.difference) <= 0.5 * 10.0**-decimals + 1e-6, c


@pytest.mark.parametrize("name", ["case 1", "case 2", "case 3", "case 4"])
def test_corrected_rows_agree_with_the_forward_kinematics(name):
    """Independent of the planner: each printed row, corrected as classified, puts the tool at its own x, y, z."""
    rows = paper000.corrected_rows(TABLE2[name])
    for row in rows:
        assert np.linalg.norm(fk_mm(row[3:]) - row[:3]) < 1e-3


@pytest.mark.parametrize("name, row", [("case 1", 7), ("case 1", 8), ("case 4", 2)])
def test_the_typos_as_printed_miss_their_own_x_y_z(name, row):
    printed = np.array(TABLE2[name].rows[row - 1], float)
    assert np.linalg.norm(fk_mm(printed[3:]) - printed[:3]) > 5.0


def test_case3_printed_q1_misses_its_x_y_and_120_deg_meets_them():
    printed = np.array(TABLE2["case 3"].rows, float)
    off = [np.linalg.norm(fk_mm(r[3:])[:2] - r[:2]) for r in printed]
    fixed = [np.linalg.norm(fk_mm([120.0, *r[4:]])[:2] - r[:2]) for r in printed]
    assert min(off) > 10.0 and max(fixed) < 1e-3


def test_case1_row5_z_is_the_extractions_reordering_of_88_3700():
    extracted = paper000.EXTRACTED[("case 1", "path", 5, "z")]
    assert sorted(extracted) == sorted("88.3700")
    row = np.array(TABLE2["case 1"].rows[4], float)
    assert fk_mm(row[3:])[2] == pytest.approx(88.3700, abs=5e-5)
    assert all(c.agrees for c in CELLS if (c.case, c.row) == ("case 1", 5))


def test_case4_triangle_is_infeasible_with_cos_alpha2_1_075():
    """Fig. 8 from the printed start [300, 0, 80, 30] and goal [47, 400, -75, 100], by the arm's geometry alone."""
    x_init, x_goal = fk_mm([300, 0, 80, 30]), fk_mm([47, 400, -75, 100])
    d = np.linalg.norm(x_goal - x_init)
    di, dg = D4 * 1e3 + 30, D4 * 1e3 + 100
    cos_a2 = (d**2 + dg**2 - di**2) / (2 * d * dg)
    assert cos_a2 == pytest.approx(1.075, abs=5e-4)
    found = paper000.new_q3(TABLE2["case 4"])
    assert found.cos_a2 == pytest.approx(cos_a2, abs=1e-9)
    assert np.isnan(found.q3_s) and np.isnan(found.q3_init_new)


def test_case3_new_q3_is_66_3187_and_the_rows_follow_66_32(run):
    found = paper000.new_q3(TABLE2["case 3"])
    assert found.q3_init_new == pytest.approx(66.3187, abs=1e-4)
    facts = run[1].paper("000").facts
    assert facts["follow_rounded"] < 5e-5 + 1e-6 < 1e-3 < facts["follow_exact"]


def test_classification_counts(run):
    _, summary = run
    counts = {p.paper: {k: p.count(k) for k in CLASSES} for p in summary.papers}
    assert counts == {"000": {TYPO: 2, ERROR: 5, OURS: 0}, "001": {TYPO: 0, ERROR: 0, OURS: 2},
                      "002": {TYPO: 2, ERROR: 6, OURS: 0}, "003": {TYPO: 0, ERROR: 0, OURS: 2}}
    p000 = summary.paper("000")
    assert (p000.reproduced, p000.compared) == (sum(c.agrees for c in CELLS), len(CELLS)) == (372, 402)
    where = {d.where for d in summary.paper("002").differences}
    assert {"eq. 1, Py", "eq. 9", "eq. 15", "eq. 16", "eqs. 24-25", "eq. 32"} <= where


def test_physics_numbers(run):
    _, summary = run
    jump = next(d for d in summary.paper("000").differences if "jumps" in d.where)
    assert "27.7 mm" in jump.shown and "0.017 mm RMS" in jump.shown
    f001 = summary.paper("001").facts
    assert f001["turns_achieved"] == pytest.approx(3.0, abs=0.01)
    assert f001["rotor_error_max_deg"] < 1.0
    assert 10 < f001["gripping_gamma_deg"][0] < f001["gripping_gamma_deg"][1] < 170
    f003 = summary.paper("003").facts
    assert f003["kci_optimised"] > f003["kci_plain"]
    assert f003["learnt_fk_median_deg"] < 1.0 < f003["paper_size_median_deg"]


def test_summary_lines_fit_one_screen(run):
    out, summary = run
    lines = summary.lines()
    assert len(lines) <= 24
    assert any("Table 2: 44 of 44 rows reproduced" in line for line in lines)
    for paper in PAPERS:
        line = next(line for line in lines if line.startswith(paper))
        part = summary.paper(paper)
        assert f"{part.reproduced} of {part.compared}" in line
        assert all(f"{k} {part.count(k)}" in line for k in CLASSES)
    assert str(out) in lines[0]


def _markdown_tables(text):
    """Each Markdown table in text as its body rows (header and rule left out)."""
    tables, current = [], None
    for line in text.splitlines():
        if line.startswith("|"):
            current = [] if current is None else current
            current.append(line)
        elif current is not None:
            tables.append(current[2:])
            current = None
    if current is not None:
        tables.append(current[2:])
    return tables


def test_files_written(run):
    out, summary = run
    for part in summary.papers:
        folder = out / part.paper
        listed = json.loads((folder / ".simbench").read_text())["files"]
        assert sorted(listed) == sorted(part.files) == sorted(p.name for p in folder.iterdir() if p.name != ".simbench")
        for name in part.files:
            path = folder / name
            if name.endswith(".csv"):
                rows = list(csv.reader(path.open()))
                assert len(rows) > 1 and {len(r) for r in rows} == {len(rows[0])}, name
            elif name.endswith(".png"):
                with Image.open(path) as image:
                    image.load()
                    assert image.size == PIXELS, name
        differences = _markdown_tables((folder / "differences.md").read_text())
        assert len(differences) == 1 and len(differences[0]) == len(part.differences)
    tables = _markdown_tables((out / "000" / "table2.md").read_text())
    assert [len(t) for t in tables] == [11, 11, 11, 11, 11, 11, 6]  # cases 1-2, 3 and 4 with their first blocks
    table2 = list(csv.DictReader((out / "000" / "table2.csv").open()))
    assert len(table2) == len(CELLS)
    assert sum(r["status"] == "reproduced" for r in table2) == 372


def test_refuses_a_folder_it_did_not_write(tmp_path):
    mine = tmp_path / "002" / "mine.txt"
    mine.parent.mkdir()
    mine.write_text("not simbench's")
    for force in (False, True):
        with pytest.raises(ScenarioError):
            reproduce("002", tmp_path, force=force)
    assert mine.read_text() == "not simbench's" and sorted(p.name for p in mine.parent.iterdir()) == ["mine.txt"]


def test_a_second_reproduction_needs_force(run):
    out, _ = run
    before = (out / "000" / "table2.csv").read_bytes()
    with pytest.raises(ScenarioError, match="exists"):
        reproduce("000", out)
    assert (out / "000" / "table2.csv").read_bytes() == before


def test_unknown_paper_is_refused(tmp_path):
    with pytest.raises(ValueError, match="000, 001, 002, 003 or all"):
        reproduce("004", tmp_path)
    assert not any(tmp_path.iterdir())


def test_the_reproduce_command_prints_the_summary_and_needs_force_the_second_time(tmp_path, capsys):
    from simbench.cli import main

    out = tmp_path / "rep"
    assert main(["reproduce", "002", "--out", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"simbench reproduce: 1 paper(s) into {out}") and any(
        line.startswith("002 ") for line in printed)
    assert (out / "002" / "index.html").is_file()
    assert main(["reproduce", "002", "--out", str(out)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert main(["reproduce", "002", "--out", str(out), "--force"]) == 0
