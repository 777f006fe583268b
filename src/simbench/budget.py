"""What a run will cost, estimated before anything big is allocated, and the refusal of what the machine cannot give.

A run's memory grows with its samples, (timing.duration + timing.hold) / sim.timestep + 1 of them (plus
sim.settle / sim.timestep steps of settling), and its video with its frames, (duration + hold) * render.fps of
render.width x render.height. Nothing bounds their product but this module: a scenario whose estimate exceeds
the machine is refused (ScenarioError, exit 2) before the model is loaded, naming the field most to blame, the
estimate, the limit and the way out; one that is large but possible gets a one-line note of its cost.

The estimate (calibrated on the shipped scenarios with their duration stretched to 30-120 s: the peak of
tracemalloc above the process's start, serially, on 2 CPU cores, MuJoCo 3.17, NumPy 2):

- Memory. A run keeps `columns` float64 numbers a sample: the trajectory (t, s, q_ref, qd_ref, tool_ref: 5 +
  2 dof) and the Recording (t, the full physics state, q, qd, force, ctrl, every sensor: 1 + nstate + 3 dof + nu +
  nsensordata; simbench.sim._Run._record), 8 * columns = R bytes: measured 388, 588, 1023 and 530 B a sample kept
  after simulating for the spherical arm, PUMA 600, RSMG and Agile Eye against R = 368, 568, 904 and 488. Planning,
  simulating and analysing peak at (tracemalloc's peak of evaluate(), 2026-11-23, recorded whole) 2.4 R
  (spherical arm case1, 40 s), 2.2 R (120 s), 2.2 R (RSMG three_turns, 30 s), 3.3 R (Agile Eye
  through_singularity, 8 s: its planner's fixed cost), 2.3 R (20 s): taken as 2.8 R. The analysis' search of
  the planned path near each sample (simbench.analysis.path_deviation) adds no term of its own: its capsule tree
  is a few columns of the path, and it searches 32,768 samples at a time. Writing the outputs (plots, the
  compressed timeseries) peaks at 4.65, 4.38, 4.31 and 3.27 R: taken as 4.5 R. Estimated against tracemalloc's
  peak of evaluate() (MB): spherical arm case1 for 40 and 120 s: 42, 124 against 35, 97; RSMG three_turns for
  30 s: 78 against 61; Agile Eye through_singularity (0.5 ms) for 8 and 20 s: 24, 57 against 27, 45
  (tests/test_budget.py holds three of them within 1/1.5 to 2). With the outputs written: 100 MB against 103 MB
  (case1, 60 s). The
  process's resident size grows 1.2-1.4 times what it allocates (its allocator's slack), on top of its
  libraries (~90 MB at import, ~150 MB once a planner's scipy and the plots' matplotlib are loaded): hence the
  limit is half of what the machine has.
  A recording stride (sim.record_every = k) keeps the full physics state and qd (nstate + dof columns) of every
  k-th sample only, R_k = 8 (columns - nstate - dof + (nstate + dof) / k) a sample, and writes every k-th: the
  run holds R_k instead of R (planning and analysing still work at every sample: 1.8 R + R_k; measured at
  stride 10 against stride 1, MB: spherical arm 30 against 35, RSMG 51 against 61, Agile Eye 24 against 27), and
  writing holds the run (R_k) while it works on the thinned outputs (3.5 R / k).
  Where the robot's summary comes a window at a time (api.Robot.streams), the pipeline analyses a strided run as
  it simulates it (simbench.sim's analyser): it holds every step's readings and the analysis' temporaries for a
  window of samples only (2.8 R a sample of the window, simbench.windowed.window_size: the whole run up to 2^15
  samples, about 8,000 beyond), and through the whole run the plan (t, s, tool_ref, q_ref, qd_ref: 5 + 2 dof
  columns), the controller's commands (nu) and the kept rows (R / k), taken 1.3 times (the plan's own series,
  the allocator's slack): calibrated on the ten-minute soak, whose resident size peaked 290 MiB above its
  libraries (estimated 299 MB; the model above gave 1.3 GB). That bounds any planner and controller; the soak's
  own now peak lower (about 175 MiB above its libraries), as the servo finds its commands a chunk at a time
  (api.Commands) and the RSMG's plan is handed back as the run passes it (pages.releasable). Writing its outputs
  then holds the thinned run only (4.5 R / k a sample: the soak's 122 MB, measured 120 MiB).
- Time: stepping 0.13 us per column per step (measured 4.4-17 us a step), planning and analysing 10 us a
  sample and 1.2 us a searched pair (the pairs of the k-d tree search the analysis used until issue 14, kept as
  the estimate, which runs high: 4 a sample, and 0.001 x the samples a sample under the 4-5-6-7 law, whose ends
  crawl longest), writing the outputs 0.5 s (the plots, with matplotlib's import) and 20 us
  a written row (measured 2026-11-23 on the shipped scenarios: 0.18-0.57 s in all; 7 us a row for the spherical
  arm's 120 s, 19-21 for the RSMG's, whose rows are widest);
  a video frame on Mesa's llvmpipe 10 ms + 40 ns a pixel (`fast`: 25 ms at 640x480, 97 ms at 1920x1080) or
  100 ms + 120 ns a pixel (`pretty`: 125 and 346 ms). A GPU renders faster: the time is a rough guide.
- Disk: the timeseries 0.75 R a sample compressed (0.66-0.70 measured), the plots 1 MB, the MP4 200 B + 0.0005 B
  a pixel a frame (x264 CRF 23 on these scenes: 288 B a 640x480 frame, 914 at 1920x1080).

Limits (Limits.of_machine): memory half of what the machine has available now (psutil's: MemAvailable, and the
cgroup's limit less its usage where lower), at most 64 GiB; time 24 h; disk the free space where the outputs go.
"""

from __future__ import annotations

import math
import os
import shutil
import sys
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

import psutil

from simbench import windowed
from simbench.errors import ScenarioError

MEMORY_FRACTION = 0.5  # of the memory available now
MEMORY_CAP = 64 * 2**30  # bytes, whatever the machine has
TIME_LIMIT = 24 * 3600.0  # s
NOTE_MEMORY = 1e9  # bytes: a run estimated above this (or NOTE_SECONDS) gets a note of its cost
NOTE_SECONDS = 300.0

_RUN_FACTOR = 2.8  # peak of planning, simulating and analysing, in retained bytes a sample
_STREAM_FACTOR = 1.3  # of the plan, the commands and the kept rows such a run holds throughout
_OUTPUT_FACTOR = 4.5  # peak while writing the outputs
_PAIRS_PER_SAMPLE = 4.0  # the time model's path search: and, for the 4-5-6-7 law, _CROWDING x the samples
_CROWDING = 0.001
_STEP_SECONDS = 0.13e-6  # a column a step
_SAMPLE_SECONDS = 10e-6
_PAIR_SECONDS = 1.2e-6
_OUTPUT_SECONDS = (0.5, 20e-6)  # fixed, a written row
_FRAME_SECONDS = {"fast": (10e-3, 40e-9), "pretty": (100e-3, 120e-9)}  # fixed, a pixel
_START_SECONDS = 0.5
_FRAMES_QUEUED = 6  # frames alive at once while rendering (simbench.render: the encoder's queue and two more)
_TIMESERIES_FACTOR = 0.75
_PLOT_BYTES = 1e6
_MP4_BYTES = (200.0, 0.0005)  # a frame, a pixel
_CGROUP_FILES = (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),  # cgroup v2, then v1
                 ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"))


@dataclass(frozen=True)
class Ask:
    """What a scenario asks of the machine, in the numbers the estimate needs: times in s, the float64 columns
    kept a sample (see the module's docstring), the video if any, and whether the outputs are written."""

    duration: float
    hold: float
    settle: float
    timestep: float
    law: str
    columns: int
    model_timestep: float
    strided: int = 0  # of the columns, those a recording stride thins: the full state and qd
    record_every: int = 1
    dof: int = 0
    nu: int = 0
    streams: bool = False  # a strided run analysed as it is simulated (api.Robot.streams)
    video: bool = False
    width: int = 640
    height: int = 480
    fps: int = 30
    quality: str = "fast"
    outputs: bool = False
    plan_seconds: float = 0.0  # the planner's own time a sample beyond _SAMPLE_SECONDS (seconds_per_sample)

    @classmethod
    def of(cls, scenario, video: bool = False, outputs: bool = False) -> Ask:
        """A scenario's ask; `video` and `outputs` as `run` is called (evaluate: neither)."""
        robot = scenario.robot_def
        columns, strided, nu, model_timestep = _model(str(robot.scene), robot.dof)
        r = scenario.render
        return cls(duration=scenario.timing.duration, hold=scenario.timing.hold, settle=scenario.sim.settle,
                   timestep=scenario.sim.timestep or model_timestep, law=scenario.timing.law, columns=columns,
                   model_timestep=model_timestep, strided=strided, record_every=scenario.sim.record_every,
                   dof=robot.dof, nu=nu, streams=scenario.sim.record_every > 1 and robot.streams,
                   video=video, width=r.width, height=r.height, fps=r.fps,
                   quality=r.quality, outputs=outputs or video,
                   plan_seconds=scenario.planner_def.seconds_per_sample)


@cache
def _model(scene: str, dof: int) -> tuple[int, int, int, float]:
    """The float64 columns a sample keeps, those of them a recording stride thins, the actuators and the model's
    own timestep, from the compiled scene (compiled once per process: the run compiles the same)."""
    import mujoco

    from simbench.plant import compiled_scene

    model = compiled_scene(scene)
    nstate = mujoco.mj_stateSize(model, int(mujoco.mjtState.mjSTATE_FULLPHYSICS))
    return 6 + 5 * dof + nstate + model.nu + model.nsensordata, nstate + dof, model.nu, float(model.opt.timestep)


@dataclass(frozen=True)
class Estimate:
    """What a run will cost: recorded samples and settling steps, frames, bytes (memory: the peak above the
    process's start; on disk: the outputs) and seconds of wall time (rough)."""

    samples: int
    settle_steps: int
    memory: int
    frames: int
    video_bytes: int
    disk: int
    seconds: float

    def summary(self) -> str:
        """The estimate in words, one line."""
        parts = [f"about {size(self.memory)} of memory and {span(self.seconds)}"]
        if self.disk:
            parts.append(f"{size(self.disk)} on disk")
        what = f"{self.samples:,} samples"
        if self.frames:
            what += f", {self.frames:,} video frames"
        return f"{', '.join(parts)} ({what})"

    def note(self) -> str | None:
        """A line on the cost of a large run (above NOTE_MEMORY or NOTE_SECONDS), or None."""
        if self.memory < NOTE_MEMORY and self.seconds < NOTE_SECONDS:
            return None
        return f"a large run: {self.summary()}"


def estimate(ask: Ask) -> Estimate:
    """The cost of a run (see the module's docstring for the model and its calibration)."""
    dt = ask.timestep
    n = int(round((ask.duration + ask.hold) / dt)) + 1
    n_settle = int(round(ask.settle / dt))
    kept = 8.0 * ask.columns
    rows = n / ask.record_every  # written
    held = 8.0 * (ask.columns - ask.strided + ask.strided / ask.record_every)  # a sample, while writing
    pairs = n * max(_PAIRS_PER_SAMPLE, _CROWDING * n if ask.law == "4567" else 0.0)
    if ask.streams:  # every step's readings a window at a time; the plan, the commands and the kept rows whole
        held = 8.0 * (5 + 2 * ask.dof + ask.nu) + kept / ask.record_every
        window = windowed.window_size(ask.timestep, n) + n_settle
        memory = _STREAM_FACTOR * held * (n + n_settle) + _RUN_FACTOR * kept * window
    else:
        memory = (_RUN_FACTOR * kept - kept + held) * (n + n_settle)
    seconds = (_START_SECONDS + _STEP_SECONDS * ask.columns * (n + n_settle)
               + (_SAMPLE_SECONDS + ask.plan_seconds) * n
               + _PAIR_SECONDS * pairs)
    disk = 0.0
    if ask.outputs:
        writing = _OUTPUT_FACTOR * kept * rows if ask.streams else held * n + (_OUTPUT_FACTOR - 1) * kept * rows
        memory = max(memory, writing)
        seconds += _OUTPUT_SECONDS[0] + _OUTPUT_SECONDS[1] * rows
        disk = _TIMESERIES_FACTOR * kept * rows + _PLOT_BYTES
    frames, video_bytes = 0, 0.0
    if ask.video:
        pixels = ask.width * ask.height
        frames = int(math.floor((ask.duration + ask.hold) * ask.fps + 1e-9)) + 1
        fixed, per_pixel = _FRAME_SECONDS.get(ask.quality, _FRAME_SECONDS["pretty"])
        seconds += frames * (fixed + per_pixel * pixels)
        video_bytes = frames * (_MP4_BYTES[0] + _MP4_BYTES[1] * pixels)
        disk += video_bytes
        memory += _FRAMES_QUEUED * 3 * pixels + 16 * frames
    return Estimate(samples=n, settle_steps=n_settle, memory=int(memory), frames=frames,
                    video_bytes=int(video_bytes), disk=int(disk), seconds=float(seconds))


@dataclass(frozen=True)
class Limits:
    """What a run may use: bytes of memory, seconds, bytes on disk where its outputs go (None: not checked), and
    where each comes from, in words."""

    memory: int
    seconds: float = TIME_LIMIT
    disk: int | None = None
    memory_basis: str = ""
    disk_basis: str = ""

    @classmethod
    def of_machine(cls, out: str | Path | None = None) -> Limits:
        """This machine's limits now: MEMORY_FRACTION of the memory available, at most MEMORY_CAP; TIME_LIMIT;
        the free space on the file system of `out` (its nearest existing folder), if given."""
        available = available_memory()
        memory = int(min(MEMORY_FRACTION * available, MEMORY_CAP))
        basis = f"{MEMORY_FRACTION:.0%} of the {size(available)} available"
        if memory == MEMORY_CAP:
            basis = f"at most {MEMORY_CAP / 2**30:g} GiB on any machine"
        disk, disk_basis = None, ""
        if out is not None:
            folder = _existing(Path(out))
            try:
                disk, disk_basis = shutil.disk_usage(folder).free, f"free at {folder}"
            except OSError:
                pass
        return cls(memory=memory, memory_basis=basis, disk=disk, disk_basis=disk_basis)


def available_memory() -> int:
    """Bytes of memory available to this process now: psutil's available memory (the kernel's MemAvailable), and
    the memory cgroup's limit less its usage where that is lower (psutil reads the whole machine's figures, not a
    container's limit)."""
    found = psutil.virtual_memory().available
    for limit_file, usage_file in _CGROUP_FILES:
        try:
            limit = int(Path(limit_file).read_text().strip())
            usage = int(Path(usage_file).read_text().strip())
        except (OSError, ValueError):  # no such cgroup, or "max": no limit
            continue
        if limit < 2**60:
            found = min(found, max(limit - usage, 0))
    return found


def _existing(path: Path) -> Path:
    """The nearest folder that exists at or above `path`."""
    path = Path(os.path.abspath(path))
    return next((p for p in (path, *path.parents) if p.is_dir()), Path(path.anchor))


# --- refusals -----------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Knob:
    """A field the way out can turn: the Ask attribute it sets, its ordinary value (None: the model's own), how
    far the schema lets it go the cheap way, and the words."""

    field: str
    attribute: str
    ordinary: float | None
    bound: float
    verb: str
    relation: str  # "at most" | "at least"
    unit: str = " s"


_KNOBS = (
    _Knob("timing.duration", "duration", 10.0, 0.01, "shorten", "at most"),
    _Knob("sim.timestep", "timestep", None, 0.01, "raise", "at least"),
    _Knob("timing.hold", "hold", 0.5, 0.0, "shorten", "at most"),
    _Knob("sim.settle", "settle", 0.2, 0.0, "shorten", "at most"),
    _Knob("render.fps", "fps", 30, 1, "lower", "at most", ""),
    _Knob("render.width", "width", 640, 64, "shrink", "at most", ""),  # and the height with it
)


def _set(ask: Ask, knob: _Knob, value: float) -> Ask:
    if knob.attribute == "fps":
        return replace(ask, fps=max(1, int(math.floor(value))))
    if knob.attribute == "width":  # the size, keeping its shape
        scale = value / ask.width
        return replace(ask, width=_even(ask.width * scale), height=_even(ask.height * scale))
    return replace(ask, **{knob.attribute: value})


def _even(x: float) -> int:
    return max(64, 2 * int(x // 2))


def _ordinary(ask: Ask, knob: _Knob) -> float:
    return ask.model_timestep if knob.ordinary is None else knob.ordinary


def _beyond(ask: Ask, knob: _Knob, value: float) -> bool:
    """Whether `value` is on the cheap side of the knob's current value."""
    current = getattr(ask, knob.attribute)
    return value > current if knob.relation == "at least" else value < current


def _blame(ask: Ask, cost, applies) -> list[_Knob]:
    """The knobs that matter, most to blame first: by how much the cost falls with the knob at its ordinary value
    (a field far out of the ordinary), then by how much it falls with the knob as far as it goes."""
    knobs = [k for k in _KNOBS if applies(k)]
    base = cost(ask)

    def fall(knob: _Knob, value: float) -> float:
        return base / max(cost(_set(ask, knob, value)), 1e-300) if _beyond(ask, knob, value) else 1.0

    return sorted(knobs, key=lambda k: (-fall(k, _ordinary(ask, k)), -fall(k, k.bound)))


def _way_out(ask: Ask, knob: _Knob, cost, limit: float) -> float | None:
    """The value of the knob nearest its current one at which the cost fits the limit, or None if none does."""
    if not _beyond(ask, knob, knob.bound) or cost(_set(ask, knob, knob.bound)) > limit:
        return None
    good, bad = knob.bound, getattr(ask, knob.attribute)
    geometric = good > 0 and bad > 0
    for _ in range(60):
        mid = math.sqrt(good * bad) if geometric else 0.5 * (good + bad)
        if cost(_set(ask, knob, mid)) <= limit:
            good = mid
        else:
            bad = mid
    return good


def _advice(ask: Ask, knob: _Knob, value: float | None) -> str:
    if value is None:
        return f"{knob.verb} {knob.field}" if knob.attribute != "width" else "shrink the video (render.width, height)"
    if knob.attribute == "fps":
        return f"lower render.fps to at most {max(1, int(math.floor(value)))}"
    if knob.attribute == "width":
        smaller = _set(ask, knob, value)
        return f"shrink the video to at most {smaller.width}x{smaller.height} (render.width, render.height)"
    return f"{knob.verb} {knob.field} to {knob.relation} {_rounded(value, up=knob.relation == 'at least')}{knob.unit}"


def _rounded(value: float, up: bool) -> str:
    """Two significant digits, rounded the safe way."""
    if value <= 0:
        return "0"
    scale = 10 ** (math.floor(math.log10(value)) - 1)
    r = (math.ceil if up else math.floor)(value / scale * (1 - 1e-12 if up else 1 + 1e-12)) * scale
    return f"{r:,.0f}" if r >= 100 else f"{r:.2g}"


def _refusal(ask: Ask, cost, limit: float, applies) -> tuple[str, str]:
    """The field to name and the way out, for a cost over its limit."""
    knobs = _blame(ask, cost, applies)
    first = knobs[0]
    value = _way_out(ask, first, cost, limit)
    advice = _advice(ask, first, value)
    if value is None:  # that field alone will not do: name the next one too
        second = next((k for k in knobs[1:] if _way_out(ask, k, cost, limit) is not None), None)
        second = second or (knobs[1] if len(knobs) > 1 else None)
        if second is not None:
            advice += f" and {_advice(ask, second, None)}"
    else:
        other = next((k for k in knobs[1:] if _way_out(ask, k, cost, limit) is not None), None)
        if other is not None:
            advice += f", or {_advice(ask, other, None)}"
    return first.field, advice


def check(scenario, video: bool = False, outputs: bool = False, out: str | Path | None = None,
          limits: Limits | None = None) -> Estimate:
    """The scenario's estimate (Ask.of), or ScenarioError naming the field most to blame where it exceeds the
    limits (default: this machine's, Limits.of_machine(out)): memory, then disk, then time."""
    ask = Ask.of(scenario, video=video, outputs=outputs)
    est = estimate(ask)
    over = over_limits(ask, est, limits if limits is not None else machine_limits(out if ask.outputs else None))
    if over is not None:
        source = scenario.source or scenario.name or "scenario"
        raise ScenarioError(source, *over)
    return est


def machine_limits(out: str | Path | None = None) -> Limits:
    """Limits.of_machine: one place for tests to replace."""
    return Limits.of_machine(out)


def over_limits(ask: Ask, est: Estimate, limits: Limits) -> tuple[str, str] | None:
    """(field, message) for the first limit the estimate exceeds, or None."""
    def physics(k: _Knob) -> bool:
        return k.attribute not in ("fps", "width")

    def any_knob(k: _Knob) -> bool:
        return ask.video or physics(k)

    how = f"{est.samples:,} samples: {ask.duration + ask.hold:g} s at a {ask.timestep:g} s timestep"
    if est.memory > limits.memory:
        field, advice = _refusal(ask, lambda a: estimate(a).memory, limits.memory, any_knob)
        basis = f" ({limits.memory_basis})" if limits.memory_basis else ""
        return field, (f"the run would need about {size(est.memory)} of memory ({how}), more than the "
                       f"{size(limits.memory)} this machine allows{basis}; {advice}")
    if limits.disk is not None and est.disk > limits.disk:
        field, advice = _refusal(ask, lambda a: estimate(a).disk, limits.disk, any_knob)
        if ask.video and est.video_bytes > 0.5 * est.disk:
            advice += ", or run with --no-video"
        basis = f" {limits.disk_basis}" if limits.disk_basis else ""
        return field, (f"the outputs would take about {size(est.disk)} on disk ({how}), more than the "
                       f"{size(limits.disk)}{basis}; {advice}")
    if est.seconds > limits.seconds:
        field, advice = _refusal(ask, lambda a: estimate(a).seconds, limits.seconds, any_knob)
        if ask.video and estimate(replace(ask, video=False)).seconds < 0.5 * est.seconds:
            advice += ", or run with --no-video"
        what = f"{est.samples:,} samples" + (f" and {est.frames:,} video frames of {ask.width}x{ask.height}"
                                              if est.frames else "")
        return field, (f"the run would take about {span(est.seconds)} ({what}), more than the "
                       f"{span(limits.seconds)} simbench allows a run; {advice}")
    return None


def announce(est: Estimate, stream=None) -> None:
    """Print the estimate's note, if any, as one line on `stream` (stderr)."""
    note = est.note()
    if note:
        print(f"note: {note}", file=stream or sys.stderr)


def size(n: float) -> str:
    """Bytes in words: 1.5 GB, 640 MB, 12 kB."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{_num(n / scale, 3)} {unit}"
    return f"{int(n)} B"


def span(seconds: float) -> str:
    """Seconds in words: 40 s, 6.5 min, 3.2 h, 12 days."""
    for unit, scale in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= scale * (2 if unit == "days" else 1):
            return f"{_num(seconds / scale, 2)} {unit}"
    return f"{_num(seconds, 2)} s"


def _num(x: float, digits: int) -> str:
    """`digits` significant digits, without an exponent from 0.01 up."""
    return f"{x:,.0f}" if x >= 10 ** digits else f"{x:.{digits}g}"
