"""The tool's distance from the planned path (the polyline of the planned tool points), whole (`path_deviation`) or
near each point's own reference (`deviation_near_reference`), by branch and bound over a tree of capsules about the
path's stretches: by hand, as scipy's cKDTree with an exact refinement slows runs and brings SciPy's 36 MiB into
runs that load none, the ten-minute soak's among them, over its memory target (BENCHMARKS.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.core import windowed
from simbench.core.windowed import norms

_BATCH = 1 << 15  # points _deviation searches at once (memory bounded on a long run)
_LEAF = 2  # the capsule tree's smallest stretches: 2^_LEAF segments, searched one by one


def path_deviation(path: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 3) from the polyline `path` (M, 3)."""
    n = len(points)
    return _deviation(np.asarray(path, float), np.asarray(points, float), [(0, n, 0, len(path) - 1)])


def deviation_near_reference(path: np.ndarray, points: np.ndarray, window: int, start: int = 0) -> np.ndarray:
    """Distance of each points[k], the tool at path sample start + k, from the stretch of the sampled path within
    about `window` samples of its own (the path cut into blocks of `window` samples, each searched with its
    neighbours), so that a path that comes back to the same place later (a rotor turning many times) does not hide
    a point that is off its own stretch. The blocks are searched a group at a time (windowed.group), each on the
    stretch of path it needs, so that the search's memory does not grow with the run. Blocks and groups are
    counted from the path's first sample: points given a window at a time (`start`) get what the run's points all
    at once get. Points and path are (N, 3)."""
    path, points = np.asarray(path, float), np.asarray(points, float)
    n = len(points)
    if start + n > len(path):
        raise ValueError(f"deviation_near_reference: {n} points from sample {start} of a path of {len(path)}")
    per = windowed.group(window, len(path)) // window  # blocks a group
    groups: dict[int, list[tuple[int, int, int, int]]] = {}
    for first in range(start - start % window, start + n, window):  # each block's first sample
        groups.setdefault(first // window // per, []).append(
            (max(first, start) - start, min(first + window, start + n) - start, path_from(first, window),
             min(first + 2 * window, len(path)) - 1))
    out = np.empty(n)
    for group in groups.values():
        a0, b0, lo, hi = group[0][0], group[-1][1], group[0][2], group[-1][3]  # block ranges ascend with start
        shifted = [(a - a0, b - a0, first - lo, last - lo) for a, b, first, last in group]
        out[a0:b0] = _deviation(path[lo:hi + 1], points[a0:b0], shifted, planned_at=start + a0 - lo)
    return out


def path_from(start: int, window: int) -> int:
    """The first path sample that `deviation_near_reference` reads for the points from sample `start` on: the
    first of the block before theirs."""
    return max(start - start % window - window, 0)


def _deviation(path: np.ndarray, points: np.ndarray, blocks: list[tuple[int, int, int, int]],
               planned_at: int | None = None) -> np.ndarray:
    """Distance of points[a:b] from the polyline path[first:last + 1], for each block (a, b, first, last).

    Exact to 1e-13 of the coordinates' scale: a branch and bound over a tree of the path's stretches of 2^l
    segments (`_capsules`), each bounded by a capsule about its chord (`_nearest`). A k-d tree's ball about a piece
    of path cannot tell apart the many pieces near a point far from a path, or near a path crawling into motion
    (hundreds of short segments in one place); a capsule, whose radius is the stretch's sag, can. `planned_at`:
    points[k] is planned at path[k + planned_at], whose segment gives the first bound. Repeated samples are
    dropped first (the polyline is the same).
    """
    if len(path) == 0:
        raise ValueError("path_deviation needs a path of at least one point")
    moved = path[1:] != path[:-1]  # repeated samples add nothing (x, y and z apart, as in `windowed.norms`)
    keep = np.concatenate([[True], moved[:, 0] | moved[:, 1] | moved[:, 2]])
    index = np.cumsum(keep) - 1  # each sample's vertex among those kept
    vertices = path[keep]
    planned = None  # each point's planned vertex, where known
    if planned_at is not None and len(points) + planned_at <= len(path):
        planned = index[planned_at:planned_at + len(points)]
    first = np.empty(len(points), int)
    last = np.empty(len(points), int)
    for a, b, lo, hi in blocks:
        first[a:b], last[a:b] = index[lo], index[hi]
    out = np.empty(len(points))
    single = first == last
    out[single] = norms(points[single] - vertices[first[single]])
    todo = np.flatnonzero(~single)
    if todo.size:
        tree = _capsules(vertices)
        for part in np.array_split(todo, -(-todo.size // _BATCH)):  # memory bounded on a long run
            guess = first[part] if planned is None else np.clip(planned[part], first[part], last[part] - 1)
            out[part] = _nearest(tree, points[part], first[part], last[part] - 1, guess)
    return out


def _distance(ax, ay, az, bx, by, bz, px, py, pz) -> np.ndarray:
    """Distance of each point p from the segment a -> b (the point a where b = a), coordinates as separate
    arrays."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    rx, ry, rz = px - ax, py - ay, pz - az
    length2 = abx * abx + aby * aby + abz * abz
    u = rx * abx + ry * aby + rz * abz
    np.divide(u, length2, out=u, where=length2 > 0)
    u[length2 <= 0] = 0.0
    np.clip(u, 0.0, 1.0, out=u)
    ex, ey, ez = rx - u * abx, ry - u * aby, rz - u * abz
    return np.sqrt(ex * ex + ey * ey + ez * ez)


@dataclass(frozen=True)
class _Capsules:
    """A polyline's vertices (padded to 2^depth segments with copies of the last; x, y and z apart) and, for
    every level l >= _LEAF, its stretches of 2^l segments each as a capsule: the chord a -> a + ab from its first
    vertex to its last and a radius r that holds the stretch. Level l's rows: ax, ay, az, abx, aby, abz,
    1 / |ab|^2 (0 for a stretch that closes) and r."""

    xyz: tuple[np.ndarray, np.ndarray, np.ndarray]
    levels: list[np.ndarray | None]  # None below _LEAF
    scale: float  # the largest coordinate


def _capsules(vertices: np.ndarray) -> _Capsules:
    """The capsule tree of a polyline of at least two vertices. A stretch's radius is its halves' larger plus the
    distance of its middle vertex from its chord: its halves' chords lie within that of its own chord (a
    segment's distance from a chord is greatest at one of its ends)."""
    segments = len(vertices) - 1
    depth = int(np.ceil(np.log2(segments))) if segments > 1 else 0
    size = 1 << depth
    x, y, z = (np.concatenate([c, np.repeat(c[-1], size - segments)]) for c in vertices.T)  # padded, apart
    levels: list[np.ndarray | None] = [None] * _LEAF
    radius = np.zeros(size)
    for level in range(1, depth + 1):
        step = 1 << level
        ax, ay, az = x[0:size:step], y[0:size:step], z[0:size:step]
        abx, aby, abz = x[step::step] - ax, y[step::step] - ay, z[step::step] - az
        length2 = abx * abx + aby * aby + abz * abz
        inverse = np.zeros_like(length2)
        np.divide(1.0, length2, out=inverse, where=length2 > 0)
        mx, my, mz = x[step // 2:size:step] - ax, y[step // 2:size:step] - ay, z[step // 2:size:step] - az
        u = np.clip((mx * abx + my * aby + mz * abz) * inverse, 0.0, 1.0)
        mx, my, mz = mx - u * abx, my - u * aby, mz - u * abz
        radius = np.maximum(radius[0::2], radius[1::2]) + np.sqrt(mx * mx + my * my + mz * mz)
        if level >= _LEAF:
            levels.append(np.array([ax, ay, az, abx, aby, abz, inverse, radius]))
    return _Capsules((x, y, z), levels, float(np.abs(vertices).max()))


def _cover(first: int, last: int) -> list[tuple[int, int]]:
    """The stretches (level, index) of a capsule tree that together are segments first..last, at most two a
    level (a segment tree's query)."""
    out, lo, hi, level = [], first, last + 1, 0
    while lo < hi:
        if lo & 1:
            out.append((level, lo))
            lo += 1
        if hi & 1:
            hi -= 1
            out.append((level, hi))
        lo, hi, level = lo >> 1, hi >> 1, level + 1
    return out


def _nearest(tree: _Capsules, points: np.ndarray, first: np.ndarray, last: np.ndarray,
             guess: np.ndarray) -> np.ndarray:
    """Each point's distance from segments first..last of the tree's polyline (the same for runs of points), to
    1e-13 of the scale of the path's and the point's coordinates (1e-12 m within 9 m of the origin).

    Branch and bound, level by level from the largest stretches that make up a point's range (`_cover`) down to
    stretches of 2^_LEAF segments, whose segments are then measured one by one: a capsule bounds its stretch's
    distance from below (the chord's distance less the radius) and from above (plus the radius). The first upper
    bound is the distance from segment `guess` or the one before it. A stretch that cannot come nearer than the
    least upper bound by the tolerance is dropped, the others split in two.
    """
    vx, vy, vz = tree.xyz
    px, py, pz = (np.ascontiguousarray(c) for c in points.T)
    count = len(points)
    tol = 1e-13 * (1.0 + np.maximum(tree.scale, np.abs(points).max(axis=1)))  # each point's: 25 times rounding's

    def exact(k: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """Each point k's distance from its segment seg, _BATCH pairs at a time (the leaves' pairs, some ten a
        point, all at once would take a dozen temporaries of them)."""
        out = np.empty(len(k))
        for a in range(0, len(k), _BATCH):
            i, s = k[a:a + _BATCH], seg[a:a + _BATCH]
            out[a:a + _BATCH] = _distance(vx[s], vy[s], vz[s], vx[s + 1], vy[s + 1], vz[s + 1], px[i], py[i], pz[i])
        return out

    everyone = np.arange(count)
    before = np.maximum(guess - 1, first)
    bound = np.minimum(exact(everyone, guess), exact(everyone, before))
    heads = np.flatnonzero(np.concatenate(([True], (first[1:] != first[:-1]) | (last[1:] != last[:-1]))))
    fresh: dict[int, list[tuple[int, int, int]]] = {}
    for a, b in zip(heads.tolist(), np.append(heads[1:], count).tolist()):
        for level, node in _cover(int(first[a]), int(last[a])):
            fresh.setdefault(level, []).append((a, b, node))
    leaves = [(np.arange(a, b).repeat(1 << level), np.tile(np.arange(node << level, (node + 1) << level), b - a))
              for level in range(_LEAF) for a, b, node in fresh.get(level, ())]  # small stretches at the ends
    k = j = np.empty(0, int)
    for level in range(len(tree.levels) - 1, _LEAF - 1, -1):
        if level in fresh:
            k = np.concatenate([k, *(np.arange(a, b) for a, b, _ in fresh[level])])
            j = np.concatenate([j, *(np.full(b - a, node) for a, b, node in fresh[level])])
        if k.size == 0:
            continue
        table = tree.levels[level]
        assert table is not None
        ax, ay, az, abx, aby, abz, inverse, radius = table.take(j, axis=1)
        rx, ry, rz = px[k] - ax, py[k] - ay, pz[k] - az
        u = (rx * abx + ry * aby + rz * abz) * inverse
        np.clip(u, 0.0, 1.0, out=u)
        rx -= u * abx
        ry -= u * aby
        rz -= u * abz
        d = np.sqrt(rx * rx + ry * ry + rz * rz)
        np.minimum.at(bound, k, d + radius)
        keep = d - radius < bound[k] - tol[k]
        k, j = k[keep], 2 * j[keep]
        k, j = np.concatenate([k, k]), np.concatenate([j, j + 1])
    span = 1 << (_LEAF - 1)  # the children of the last level's stretches, segment by segment
    leaves.append((np.repeat(k, span), (j[:, None] * span + np.arange(span)).ravel()))
    k, seg = (np.concatenate(parts) for parts in zip(*leaves))
    if k.size:
        np.minimum.at(bound, k, exact(k, seg))
    return bound
