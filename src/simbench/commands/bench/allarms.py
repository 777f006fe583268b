"""A bench of several arms: index.html opens on a grid of arms by methods (each cell the method's ok share and
deviation p95 on that arm, from the leaderboard), each arm's name and cells linking the arm's own page,
arm-<robot>.html beside index.html (so that it shows plots/ and links scenarios/ by the same relative paths), which
holds that arm's rows of every table and its plots.
"""

from __future__ import annotations

from simbench.outputs.page.html import esc, href, number


def arm_page(robot: str) -> str:
    """The file name of `robot`'s own page, relative to the bench's folder."""
    return f"arm-{robot}.html"


def of_robot(columns: dict[str, list], robot: str) -> dict[str, list]:
    """The rows of a table (columns with a `robot` column) that are `robot`'s."""
    if not columns:
        return columns
    keep = [i for i, name in enumerate(columns["robot"]) if name == robot]
    return {name: [values[i] for i in keep] for name, values in columns.items()}


def grid(leaderboard: dict[str, list], robots: list[str], methods: list[str]) -> str:
    """The arms-by-methods table: a cell per robot and method, `ok share / deviation p95 mm` linked to the arm's
    page, or `not run` where the method does not apply to the arm."""
    cells = {(r, m): i for i, (r, m) in enumerate(zip(leaderboard.get("robot", []), leaderboard.get("method", [])))}
    head = "<th>arm</th>" + "".join(f"<th>{esc(method)}</th>" for method in methods)
    body = []
    for robot in robots:
        page = href(arm_page(robot))
        row = [f'<td class="key"><a href="{page}">{esc(robot)}</a></td>']
        for method in methods:
            i = cells.get((robot, method))
            if i is None:
                row.append('<td class="note">not run</td>')
                continue
            ok, deviation = leaderboard["ok_share"][i], leaderboard["deviation_p95_mm"][i]
            shown = f"{number(ok, 3)} / {number(deviation, 3)}{'' if deviation is None else ' mm'}"
            row.append(f'<td class="n"><a href="{page}">{esc(shown)}</a></td>')
        body.append(f"<tr>{''.join(row)}</tr>\n")
    return ('<h2 id="arms">All arms</h2>\n<p class="note">Each cell: the share of tasks ok / the 95th percentile of '
            "the largest deviation from the path (mm), over the arm's tasks by that method; an arm's name or a cell "
            "opens the arm's page.</p>\n"
            f'<div class="scroll"><table><thead><tr>{head}</tr></thead>\n<tbody>\n{"".join(body)}</tbody></table>'
            "</div>\n")
