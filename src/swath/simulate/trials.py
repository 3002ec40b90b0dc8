"""Sanding trials run in swath's own simulator: the depths a shop would measure, for closing the
calibration loop (``swath doe`` → trials → ``swath calibrate`` → ``swath plan --calibration``).

A trial (:mod:`swath.simulate.calibrate`) is ``passes`` straight passes, back and forth along one
track, of a flat pad over a flat plate; its depth is measured at the middle of the track's centre
line.  :func:`simulate_trial` runs it through :func:`swath.simulate.simulate_removal` — the same
contact model and Preston integration as a job — with the pad wearing along the way
(``k_p(a) = k_p0 · exp(−λ a)``, ``a`` the media's time in contact, starting from ``start_age``),
and returns the centre-line depth and the media's age at the middle of the trial (what the trials
CSV's ``pad_age_s`` records).  :func:`fill_trials` fills a trials template (the CSV ``swath doe``
writes) with such depths, each times ``exp(noise · N(0, 1))`` (seeded), so that a fit has a known
answer to find.
"""

from __future__ import annotations

import csv
import functools
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..contact import Tool
from ..errors import InputError
from ..io.atomic import write_text_atomic


@dataclass(frozen=True)
class TrialResult:
    """One simulated trial.

    Attributes
    ----------
    depth : float
        Centre-line depth at the middle of the track, m.
    mid_age : float
        The media's time in contact at the middle of the trial, s.
    contact_time : float
        The trial's own time in contact, s.
    """

    depth: float
    mid_age: float
    contact_time: float


def trial_tool(*, force: float, spindle_speed_rpm: float, orbit_radius: float, pad_radius: float,
               preston: float, wear_rate: float = 0.0) -> Tool:
    """The :class:`Tool` of a trials row (``orbit_radius`` 0 = a rotary pad)."""
    return Tool(pad_radius=pad_radius, force=force, spindle_speed=spindle_speed_rpm * 2 * math.pi / 60.0,
                motion="orbital" if orbit_radius > 0 else "rotary",
                orbit_radius=orbit_radius if orbit_radius > 0 else 2.5e-3, preston=preston, wear_rate=wear_rate)


def simulate_trial(tool: Tool, *, feed: float, passes: int, start_age: float = 0.0, sample_spacing: float = 1.5e-3,
                   track_margin: float = 0.012) -> TrialResult:
    """Simulate one trial with ``tool`` (its ``preston`` the fresh media's, its ``wear_rate`` λ).

    The plate and the track are sized to the pad: the track runs ``4R + 2·track_margin`` long, so
    the middle of the centre line passes under the whole pad on every pass.
    """
    from ..process import media_schedule
    from .removal import simulate_removal

    if not (feed > 0 and passes >= 1 and start_age >= 0):
        raise InputError(f"a trial needs a positive feed, at least one pass and an age >= 0, got {feed!r}, "
                         f"{passes!r}, {start_age!r}")
    plate, tr, (x0, x1, y) = _trial_track(float(tool.pad_radius), float(feed), int(passes), float(sample_spacing),
                                          float(track_margin))
    sched = media_schedule(tr, tool.wear_rate)
    scale = np.exp(-tool.wear_rate * (start_age + sched.age))
    rm = simulate_removal(tr, plate, tool, sample_spacing=sample_spacing, rate_scale=scale, sampling="lattice")
    v = rm.surface.vertices
    mid = (np.abs(v[:, 0] - 0.5 * (x0 + x1)) <= 2.5 * sample_spacing) & (np.abs(v[:, 1] - y) <= 1.01 * sample_spacing)
    if not mid.any():
        raise InputError("no removal sample at the middle of the trial's track; use a finer sample spacing")
    contact = float(sched.age.max())
    return TrialResult(float(np.mean(rm.depth[mid])), start_age + 0.5 * contact, contact)


@functools.lru_cache(maxsize=32)
def _trial_track(R: float, feed: float, passes: int, sample_spacing: float, track_margin: float):
    """(plate, timed trajectory, (x0, x1, y)) of a trial: the same for every force and pad speed."""
    from ..examples import flat_plate
    from ..plan import Pass, ToolPath
    from ..trajectory import FeedLimit, time_path

    half = 2 * R + track_margin
    width = 2 * R + 4 * sample_spacing
    plate = flat_plate(size_x=2 * half + 2 * R, size_y=width, spacing=min(5e-3, sample_spacing * 2))
    x0, x1, y = R, R + 2 * half, width / 2
    normal = np.array([[0.0, 0.0, 1.0]] * 2)
    forward = Pass(np.array([[x0, y, 0.0], [x1, y, 0.0]]), normal)
    track = tuple(forward if k % 2 == 0 else forward.reversed() for k in range(passes))
    return plate, time_path(ToolPath(plate, track, "trial"), [FeedLimit(feed)]), (x0, x1, y)


def fill_trials(template, out, *, preston: float, wear_rate: float = 0.0, noise: float = 0.0, seed: int = 0,
                sample_spacing: float = 1.5e-3, overwrite: bool = False) -> Path:
    """Fill the blank ``depth_m`` of a trials template with simulated depths; returns ``out``.

    Parameters
    ----------
    template : str or Path
        A trials CSV (``swath doe``): force, spindle speed, orbit, pad radius, feed, passes, and
        ``pad_age_s`` (the media's pre-wear at the trial's start, s; blank = fresh).
    out : str or Path
        The filled CSV; ``pad_age_s`` becomes the age at the middle of each trial.
    preston : float
        The fresh media's Preston coefficient ``k_p0``, 1/Pa.
    wear_rate : float
        ``λ``, 1/s.
    noise : float
        Relative scatter of a measurement (log-normal, e.g. 0.08).
    seed : int
        Seed of the scatter.
    """
    out = Path(out)
    if out.exists() and not overwrite:
        raise InputError(f"{out} exists; choose another name or pass overwrite=True")
    with open(template, encoding="utf-8", newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
        header = list(reader.fieldnames or [])
    for col in ("depth_m", "pad_age_s"):
        if col not in header:
            header.append(col)
    rng = np.random.default_rng(seed)
    for r in rows:
        num = lambda k, d=None: float(r[k]) if (r.get(k) or "").strip() else d
        tool = trial_tool(force=num("force_N"), spindle_speed_rpm=num("spindle_speed_rpm"),
                          orbit_radius=num("orbit_radius_m", 0.0), pad_radius=num("pad_radius_m", 0.0381),
                          preston=preston, wear_rate=wear_rate)
        res = simulate_trial(tool, feed=num("feed_m_per_s"), passes=int(num("passes")),
                             start_age=num("pad_age_s", 0.0), sample_spacing=sample_spacing)
        r["depth_m"] = f"{res.depth * math.exp(noise * rng.standard_normal()):.6e}"
        r["pad_age_s"] = f"{res.mid_age:.3f}"
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=header, lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out, buf.getvalue())
    return out


def hold_back(rows: list, *, every: int = 4, first: int = 2) -> tuple[list, list]:
    """Split trials rows into ``(fitted, held_back)``: every ``every``-th row from ``first`` is held
    back to check a calibration on trials it was not fitted to."""
    if every < 2 or not 0 <= first < every:
        raise InputError(f"hold_back needs every >= 2 and 0 <= first < every, got {every!r}, {first!r}")
    held = set(range(first, len(rows), every))
    return [r for i, r in enumerate(rows) if i not in held], [r for i, r in enumerate(rows) if i in held]


def trial_depth(tool: Tool, row: dict, *, sample_spacing: float = 1.5e-3) -> float:
    """Depth (m) ``tool`` removes in the trial a filled trials ``row`` describes (its feed, passes,
    force and ``pad_age_s``, the media's age at the trial's middle as :func:`fill_trials` writes it).

    The trial starts half its own contact time (from its timed track) before the row's mid age.
    """
    from ..process import media_schedule

    feed, passes = float(row["feed_m_per_s"]), int(float(row["passes"]))
    tool = tool.with_force(float(row["force_N"]))
    _, track, _ = _trial_track(float(tool.pad_radius), feed, passes, float(sample_spacing), 0.012)
    contact = float(media_schedule(track, 0.0).age.max())
    start = max(float(row.get("pad_age_s") or 0.0) - 0.5 * contact, 0.0)
    return simulate_trial(tool, feed=feed, passes=passes, start_age=start, sample_spacing=sample_spacing).depth
