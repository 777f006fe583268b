"""What a run will cost, estimated before anything big is allocated, and the refusal of what the machine cannot give.

A run's memory grows with its samples and its video with its frames, and nothing bounds their product but this
module: a scenario whose estimate exceeds the machine is refused (ScenarioError, exit 2) before the model is
loaded, naming the field most to blame, the estimate, the limit and the way out; one that is large but possible
gets a one-line note of its cost. The model (memory: the float64 columns kept a sample, _model, times the factors
below; time: per step, sample, searched pair, written row and pixel; disk: per sample, plot and pixel) and its
calibration on the shipped scenarios: BENCHMARKS.md, "The run's cost estimate". Limits (Limits.of_machine): half
the memory available now (the libraries and the allocator's slack come on top), at most 64 GiB; 24 h; the free
space where the outputs go.
"""
from __future__ import annotations

import math
import shutil
import sys
from contextlib import suppress
from dataclasses import dataclass, replace
from functools import cache
from pathlib import Path

import psutil

from simbench.core import windowed
from simbench.core.errors import ScenarioError, nearest_folder

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
_FRAMES_QUEUED = 6  # frames alive at once while rendering (simbench.outputs.render: the encoder's queue and two more)
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

    from simbench.core.plant import compiled_scene

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
        disk = f", {size(self.disk)} on disk" if self.disk else ""
        frames = f", {self.frames:,} video frames" if self.frames else ""
        return f"about {size(self.memory)} of memory and {span(self.seconds)}{disk} ({self.samples:,} samples{frames})"

    def note(self) -> str | None:
        """A line on the cost of a large run (above NOTE_MEMORY or NOTE_SECONDS), or None."""
        if self.memory < NOTE_MEMORY and self.seconds < NOTE_SECONDS:
            return None
        return f"a large run: {self.summary()}"


def estimate(ask: Ask) -> Estimate:
    """The cost of a run (the model and its calibration: BENCHMARKS.md, "The run's cost estimate")."""
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
        """This machine's limits now (the module's constants); disk: the free space where `out` goes, if given."""
        available = available_memory()
        memory = int(min(MEMORY_FRACTION * available, MEMORY_CAP))
        basis = f"{MEMORY_FRACTION:.0%} of the {size(available)} available"
        if memory == MEMORY_CAP:
            basis = f"at most {MEMORY_CAP / 2**30:g} GiB on any machine"
        disk, disk_basis = None, ""
        if out is not None:
            folder = nearest_folder(out)
            with suppress(OSError):
                disk, disk_basis = shutil.disk_usage(folder).free, f"free at {folder}"
        return cls(memory=memory, memory_basis=basis, disk=disk, disk_basis=disk_basis)


def available_memory() -> int:
    """Bytes of memory available to this process now: psutil's, or the memory cgroup's limit less its usage where
    lower (psutil reads the whole machine's figures, not a container's limit)."""
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
        width, height = (max(64, 2 * int(x * scale // 2)) for x in (ask.width, ask.height))  # even, as Render's
        return replace(ask, width=width, height=height)
    return replace(ask, **{knob.attribute: value})


def _beyond(ask: Ask, knob: _Knob, value: float) -> bool:
    """Whether `value` is on the cheap side of the knob's current value."""
    current = getattr(ask, knob.attribute)
    return value > current if knob.relation == "at least" else value < current


def _blame(ask: Ask, cost) -> list[_Knob]:
    """The knobs that matter, most to blame first: by how much the cost falls with the knob at its ordinary value
    (a field far out of the ordinary), then by how much it falls with the knob as far as it goes."""
    knobs = [k for k in _KNOBS if ask.video or k.attribute not in ("fps", "width")]  # the video's if there is one
    base = cost(ask)

    def fall(knob: _Knob, value: float) -> float:
        return base / max(cost(_set(ask, knob, value)), 1e-300) if _beyond(ask, knob, value) else 1.0

    ordinary = {k: ask.model_timestep if k.ordinary is None else k.ordinary for k in knobs}
    return sorted(knobs, key=lambda k: (-fall(k, ordinary[k]), -fall(k, k.bound)))


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


def _refusal(ask: Ask, cost, limit: float) -> tuple[str, str]:
    """The field to name and the way out, for a cost over its limit."""
    knobs = _blame(ask, cost)
    first = knobs[0]
    value = _way_out(ask, first, cost, limit)
    advice = _advice(ask, first, value)
    other = next((k for k in knobs[1:] if _way_out(ask, k, cost, limit) is not None), None)
    if value is None:  # that field alone will not do: name the next one too
        other = other or next(iter(knobs[1:]), None)
    if other is not None:
        advice += f"{' and' if value is None else ', or'} {_advice(ask, other, None)}"
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
    how = f"{est.samples:,} samples: {ask.duration + ask.hold:g} s at a {ask.timestep:g} s timestep"
    if est.memory > limits.memory:
        field, advice = _refusal(ask, lambda a: estimate(a).memory, limits.memory)
        basis = f" ({limits.memory_basis})" if limits.memory_basis else ""
        return field, (f"the run would need about {size(est.memory)} of memory ({how}), more than the "
                       f"{size(limits.memory)} this machine allows{basis}; {advice}")
    if limits.disk is not None and est.disk > limits.disk:
        field, advice = _refusal(ask, lambda a: estimate(a).disk, limits.disk)
        if ask.video and est.video_bytes > 0.5 * est.disk:
            advice += ", or run with --no-video"
        basis = f" {limits.disk_basis}" if limits.disk_basis else ""
        return field, (f"the outputs would take about {size(est.disk)} on disk ({how}), more than the "
                       f"{size(limits.disk)}{basis}; {advice}")
    if est.seconds > limits.seconds:
        field, advice = _refusal(ask, lambda a: estimate(a).seconds, limits.seconds)
        if ask.video and estimate(replace(ask, video=False)).seconds < 0.5 * est.seconds:
            advice += ", or run with --no-video"
        what = f"{est.samples:,} samples" + (f" and {est.frames:,} video frames of {ask.width}x{ask.height}"
                                              if est.frames else "")
        return field, (f"the run would take about {span(est.seconds)} ({what}), more than the "
                       f"{span(limits.seconds)} simbench allows a run; {advice}")
    return None


def announce(est: Estimate) -> None:
    """Print the estimate's note, if any, as one line on stderr."""
    note = est.note()
    if note:
        print(f"note: {note}", file=sys.stderr)


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
