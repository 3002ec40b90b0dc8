"""Preston calibration from sanding trials (Jaeger ch. 6): fit, uncertainty, calibration file, prediction.

Trials
------
A trial is a straight pass (repeated ``passes`` times along the same track) of a flat pad over a
flat test plate; its measured ``depth`` is the removal at the centre line of the track.  The trials
CSV has one header line, ``,`` separators, ``.`` decimals, units in the column names:

=====================  ========  ==================================================================
column                 required  meaning
=====================  ========  ==================================================================
``trial``              no        label of the trial
``grit``               no        abrasive grit (or any label); one Preston coefficient is fitted per
                                 grit (default: all trials form one group ``"all"``)
``force_N``            yes       normal force, N
``spindle_speed_rpm``  yes       pad (or orbit) speed, rpm
``orbit_radius_m``     no        orbit eccentricity of an orbital pad, m; ``0`` or absent = rotary pad
``pad_radius_m``       no        pad radius, m (default: the ``pad_radius`` argument)
``feed_m_per_s``       yes       feed along the pass, m/s
``passes``             yes       passes over the same track (positive integer)
``depth_m``            yes       measured centre-line depth after all passes, m (a blank cell marks
                                 a trial not yet run: the row is skipped)
``hardness_Pa``        no        hardness of the material, Pa (for Archard's dimensionless coefficient)
``pad_age_s``          no        the media's time in contact at the middle of the trial, s (fresh
                                 media: 0); given on every row, the pad wear rate is fitted too
=====================  ========  ==================================================================

Model
-----
On a flat plate the tool model's pressure is uniform, ``p = F / (π R²)``.  A point on the centre
line is under the pad for ``2R / v_f``; Preston's law integrated over that time gives

* orbital pad (relative speed ``v = ω·e`` everywhere): ``d = k_p · n · p · ω e · 2R / v_f``
* rotary pad (``v = ω r``, ``r = |v_f τ|`` on the centre line): ``d = k_p · n · p · ω R² / v_f``

i.e. ``d = k_p · X`` with the *exposure* ``X`` (Pa·m) of :func:`exposure`.  With ``fit_exponents``
the law is ``d = k_p · n · p^a · ∫ v^b dτ`` (orbital ``∫ = (ω e)^b 2R/v_f``, rotary
``2 ω^b R^(b+1) / ((b+1) v_f)``), fitted by least squares on ``log d``.

Uncertainty
-----------
``error_model="relative"`` (default): each trial gives ``k_i = d_i / X_i``; ``k_p`` is their mean
and its interval the Student-t interval (exact for normal errors proportional to depth).
``"absolute"``: least squares through the origin, ``k_p = Σ X d / Σ X²``, Student-t interval with
``n − 1`` degrees of freedom (exact for normal errors of constant size).  Exponent fits: Gauss–Newton
covariance ``s² (JᵀJ)⁻¹`` of the log-model, Student-t with ``n − 3`` degrees of freedom.

Pad wear
--------
Abrasive cuts less as it wears: ``k_p(a) = k_p0 · exp(−λ a)`` with ``a`` the media's time in
contact (:attr:`swath.contact.Tool.wear_rate` is ``λ``, 1/s).  With ``pad_age_s`` on every trial
(and at least two distinct ages) the fit is ``log(d / X) = log k_p0 − λ a`` by least squares
(relative errors), ``k_p0`` the fresh media's coefficient; its interval and ``λ``'s are Student-t
with ``n − 2`` degrees of freedom.  A trial's depth is the mean of ``exp(−λ a)`` over the passes,
which the age at its middle matches to ``(λ T)² / 24`` (``T`` the trial's time in contact).

Tool record
-----------
The calibration file states the tool the trials were run with (``metadata["tool"]``: motion,
spindle speed, orbit radius, pad radius, the force and feed ranges); :func:`calibrated_tool`
builds a job's tool from it, refusing a job that runs the pad in another motion.

Archard's wear law ``h = K/H · p · s`` (``s`` the sliding distance ``∫ v dτ``) gives the same
profile under the same uniform pressure (Jaeger 6.2.2), so its dimensional wear coefficient
``K/H`` (m³ per N·m) equals ``k_p``; with a hardness ``H`` the dimensionless ``K = k_p · H``.
"""

from __future__ import annotations

import csv
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.atomic import write_text_atomic

log = logging.getLogger(__name__)

#: Columns of the trials CSV and their meaning (see the module docstring).
TRIAL_COLUMNS = {
    "trial": "label of the trial (optional)",
    "grit": "abrasive grit or group label (optional)",
    "force_N": "normal force, N",
    "spindle_speed_rpm": "pad or orbit speed, rpm",
    "orbit_radius_m": "orbit eccentricity of an orbital pad, m; 0 or absent = rotary (optional)",
    "pad_radius_m": "pad radius, m (optional)",
    "feed_m_per_s": "feed along the pass, m/s",
    "passes": "passes over the same track",
    "depth_m": "measured centre-line depth after all passes, m",
    "hardness_Pa": "material hardness, Pa (optional, for Archard's coefficient)",
    "pad_age_s": "the media's time in contact at the middle of the trial, s (optional, to fit pad wear)",
}
_REQUIRED = ("force_N", "spindle_speed_rpm", "feed_m_per_s", "passes", "depth_m")
CALIBRATION_FORMAT = "swath-preston-calibration"


@dataclass(frozen=True)
class Trials:
    """Trials as SI arrays, one entry per trial.

    Attributes
    ----------
    grit : (n,) str
    force : (n,) float          normal force, N
    omega : (n,) float          spindle speed, rad/s
    orbit_radius : (n,) float   m (0 = rotary)
    pad_radius : (n,) float     m
    feed : (n,) float           m/s
    passes : (n,) float
    depth : (n,) float          m
    hardness : (n,) float       Pa (NaN where not given)
    pad_age : (n,) float        the media's time in contact at the trial's middle, s (NaN where not given)
    """

    grit: np.ndarray
    force: np.ndarray
    omega: np.ndarray
    orbit_radius: np.ndarray
    pad_radius: np.ndarray
    feed: np.ndarray
    passes: np.ndarray
    depth: np.ndarray
    hardness: np.ndarray
    pad_age: np.ndarray

    def __len__(self) -> int:
        return len(self.depth)

    def subset(self, mask: np.ndarray) -> Trials:
        return Trials(**{k: getattr(self, k)[mask] for k in self.__dataclass_fields__})

    @property
    def pressure(self) -> np.ndarray:
        """(n,) pad pressure on flat ``F / (π R²)``, Pa."""
        return self.force / (math.pi * self.pad_radius**2)


def make_trials(*, force, spindle_speed, feed, passes, depth, pad_radius=0.0381, orbit_radius=0.0,
                grit="all", hardness=math.nan, pad_age=math.nan) -> Trials:
    """Trials from SI arrays (broadcast to a common length).

    Parameters
    ----------
    force : (n,) float            N
    spindle_speed : (n,) float    rad/s
    feed : (n,) float             m/s
    passes : (n,) float           count
    depth : (n,) float            measured centre-line depth, m
    pad_radius : (n,) float       m
    orbit_radius : (n,) float     m (0 = rotary pad)
    grit : (n,) str               group label
    hardness : (n,) float         Pa
    pad_age : (n,) float          the media's time in contact at the trial's middle, s
    """
    arrs: list[np.ndarray] = list(np.broadcast_arrays(np.asarray(force, float), np.asarray(spindle_speed, float), np.asarray(feed, float),
                               np.asarray(passes, float), np.asarray(depth, float), np.asarray(pad_radius, float),
                               np.asarray(orbit_radius, float), np.asarray(hardness, float),
                               np.asarray(pad_age, float)))
    n = arrs[0].shape[0] if arrs[0].ndim else 1
    arrs = [np.atleast_1d(a).astype(float).copy() for a in arrs]
    g = np.broadcast_to(np.asarray(grit, dtype=object), (n,)).astype(str)
    t = Trials(g, arrs[0], arrs[1], arrs[6], arrs[5], arrs[2], arrs[3], arrs[4], arrs[7], arrs[8])
    _validate(t)
    return t


def _validate(t: Trials) -> None:
    checks = (("force_N", t.force, False), ("spindle_speed_rpm", t.omega, False), ("feed_m_per_s", t.feed, False),
              ("passes", t.passes, False), ("depth_m", t.depth, False), ("pad_radius_m", t.pad_radius, False),
              ("orbit_radius_m", t.orbit_radius, True))
    for name, a, zero_ok in checks:
        bad = ~np.isfinite(a) | ((a < 0) if zero_ok else (a <= 0))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"trial {i + 1}: {name} must be a {'non-negative' if zero_ok else 'positive'} number, "
                             f"got {a[i]!r}")
    bad = np.isfinite(t.pad_age) & (t.pad_age < 0)
    if bad.any():
        raise InputError(f"trial {int(np.flatnonzero(bad)[0]) + 1}: pad_age_s must be a time in contact >= 0 s")
    if np.any(t.orbit_radius >= t.pad_radius):
        raise InputError("orbit_radius_m must be smaller than the pad radius")


def read_trials(path, *, pad_radius: float = 0.0381) -> Trials:
    """Read a trials CSV (module docstring); rows with a blank ``depth_m`` are skipped.

    Parameters
    ----------
    path : str or Path
    pad_radius : float
        Pad radius for rows without ``pad_radius_m``, m.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8", newline="") as fh:
            reader = csv.DictReader(fh)
            rows = list(reader)
            header = [h.strip() for h in (reader.fieldnames or [])]
    except OSError as exc:
        raise InputError(f"cannot read trials {path}: {exc}") from exc
    missing = [c for c in _REQUIRED if c not in header]
    if missing:
        raise InputError(f"trials {path}: expected columns {', '.join(_REQUIRED)} (units in the names), "
                         f"missing {', '.join(missing)}; write a template with `swath doe`")
    done = [r for r in rows if (r.get("depth_m") or "").strip() != ""]
    if len(done) < len(rows):
        log.info("trials %s: %d of %d rows have no measured depth_m yet and are skipped", path, len(rows) - len(done),
                 len(rows))

    def col(name, default):
        out = []
        for i, r in enumerate(done):
            text = (r.get(name) or "").strip()
            if text == "":
                out.append(default)
                continue
            try:
                out.append(float(text))
            except ValueError:
                raise InputError(f"trials {path}, data row {i + 1}: {name} must be a number, got {text!r}") from None
        return np.array(out, float)

    if not done:
        raise InputError(f"trials {path}: no row has a measured depth_m")
    for name in _REQUIRED:
        if any((r.get(name) or "").strip() == "" for r in done):
            raise InputError(f"trials {path}: every measured row needs {name}")
    grit = np.array([(r.get("grit") or "").strip() or "all" for r in done], dtype=str)
    t = Trials(grit, col("force_N", math.nan), col("spindle_speed_rpm", math.nan) * (2 * math.pi / 60),
               col("orbit_radius_m", 0.0), col("pad_radius_m", pad_radius), col("feed_m_per_s", math.nan),
               col("passes", math.nan), col("depth_m", math.nan), col("hardness_Pa", math.nan),
               col("pad_age_s", math.nan))
    _validate(t)
    return t


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------
def _log_speed_integral(t: Trials, b: float) -> np.ndarray:
    """log ∫ v^b dτ over the centre line's time under the pad, per trial."""
    R, v, w, e = t.pad_radius, t.feed, t.omega, t.orbit_radius
    orbital = e > 0
    with np.errstate(divide="ignore"):
        lo = b * np.log(np.where(orbital, w * e, 1.0)) + np.log(2 * R / v)
        lr = math.log(2) + b * np.log(w) + (b + 1) * np.log(R) - np.log(v) - math.log(b + 1)
    return np.where(orbital, lo, lr)


def exposure(trials: Trials) -> np.ndarray:
    """(n,) Preston exposure ``X = n · p · ∫ v dτ`` of each trial, Pa·m: the depth per unit ``k_p``."""
    return trials.passes * trials.pressure * np.exp(_log_speed_integral(trials, 1.0))


def _log_model(theta, t: Trials) -> np.ndarray:
    logk, a, b = theta
    return logk + np.log(t.passes) + a * np.log(t.pressure) + _log_speed_integral(t, b)


@dataclass(frozen=True)
class PrestonFit:
    """One fitted group (grit).

    Attributes
    ----------
    grit : str
    preston : float
        ``k_p``: 1/Pa when both exponents are 1, else m·Pa⁻ᵃ·(m/s)⁻ᵇ·s⁻¹.
    preston_low, preston_high : float
        Confidence interval of ``k_p`` at ``confidence``.
    confidence : float
    pressure_exponent, speed_exponent : float
        ``a`` and ``b`` (1 unless fitted).
    pressure_exponent_interval, speed_exponent_interval : (2,) float
        Their intervals (NaN unless fitted).
    n_trials : int
    error_model : str
        ``"relative"``, ``"absolute"`` or ``"log"`` (exponent fit).
    residual_std : float
        Relative (``relative``, ``log``: of ``log d``) or absolute (m) residual scatter.
    dof : int
        Degrees of freedom of the interval.
    covariance : (q, q) float
        Covariance of the fitted parameters (``k_p`` alone, or ``log k_p, a, b``).
    hardness : float
        Mean material hardness of the group, Pa (NaN if not given).
    wear_rate : float
        Pad wear ``λ``, 1/s (0 unless fitted from ``pad_age_s``); ``preston`` is then the fresh
        media's ``k_p0``.
    wear_rate_interval : (2,) float
        Its interval at ``confidence`` (NaN unless fitted).
    """

    grit: str
    preston: float
    preston_low: float
    preston_high: float
    confidence: float
    pressure_exponent: float = 1.0
    speed_exponent: float = 1.0
    pressure_exponent_interval: tuple = (math.nan, math.nan)
    speed_exponent_interval: tuple = (math.nan, math.nan)
    n_trials: int = 0
    error_model: str = "relative"
    residual_std: float = math.nan
    dof: int = 0
    covariance: tuple = ()
    hardness: float = math.nan
    wear_rate: float = 0.0
    wear_rate_interval: tuple = (math.nan, math.nan)

    @property
    def linear(self) -> bool:
        """True when both exponents are 1 (plain Preston, ``k_p`` in 1/Pa)."""
        return self.pressure_exponent == 1.0 and self.speed_exponent == 1.0

    @property
    def archard_coefficient(self) -> float:
        """Archard's dimensionless wear coefficient ``K = k_p · H`` (NaN without hardness or for
        exponent fits)."""
        return self.preston * self.hardness if self.linear else math.nan

    def predict(self, trials: Trials, *, confidence: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Centre-line depth (m) of ``trials`` (no depth needed) with the confidence interval of its
        mean and the prediction interval of one new trial.

        Returns
        -------
        depth, low, high, pred_low, pred_high : (n,) float, m
        """
        from scipy import stats

        level = self.confidence if confidence is None else confidence
        tq = stats.t.ppf(0.5 + level / 2, self.dof) if self.dof > 0 else math.inf
        cov = np.asarray(self.covariance, float)
        if self.error_model == "wear":
            age = np.where(np.isfinite(trials.pad_age), trials.pad_age, 0.0)
            J = np.column_stack([np.ones(len(trials)), -age])
            mu = math.log(self.preston) - self.wear_rate * age + np.log(exposure(trials))
            var = np.einsum("ij,jk,ik->i", J, cov, J)
            sd, sp = np.sqrt(var), np.sqrt(var + self.residual_std**2)
            d = np.exp(mu)
            return d, np.exp(mu - tq * sd), np.exp(mu + tq * sd), np.exp(mu - tq * sp), np.exp(mu + tq * sp)
        if self.error_model == "log":
            theta = np.array([math.log(self.preston), self.pressure_exponent, self.speed_exponent])
            mu = _log_model(theta, trials)
            J = _jacobian(theta, trials)
            var = np.einsum("ij,jk,ik->i", J, cov, J)
            sd, sp = np.sqrt(var), np.sqrt(var + self.residual_std**2)
            d = np.exp(mu)
            return d, np.exp(mu - tq * sd), np.exp(mu + tq * sd), np.exp(mu - tq * sp), np.exp(mu + tq * sp)
        X = exposure(trials)
        d = self.preston * X
        se = math.sqrt(cov[0, 0]) if cov.size else 0.0
        if self.error_model == "relative":
            rel_mean = tq * se / self.preston
            rel_pred = tq * math.sqrt(se**2 / self.preston**2 + self.residual_std**2)
            return d, d * (1 - rel_mean), d * (1 + rel_mean), d * (1 - rel_pred), d * (1 + rel_pred)
        half = tq * se * X
        halfp = tq * np.sqrt((se * X) ** 2 + self.residual_std**2)
        return d, d - half, d + half, d - halfp, d + halfp


def _jacobian(theta, t: Trials, h: float = 1e-6) -> np.ndarray:
    base = _log_model(theta, t)
    J = np.empty((len(t), 3))
    for j in range(3):
        th = np.array(theta, float)
        th[j] += h
        J[:, j] = (_log_model(th, t) - base) / h
    return J


@dataclass(frozen=True)
class Calibration:
    """Fitted Preston coefficients, one per grit, with their intervals.

    Attributes
    ----------
    fits : dict of str -> PrestonFit
    metadata : dict
        Where the trials came from and how they were fitted.
    """

    fits: dict
    metadata: dict = field(default_factory=dict)

    def fit_for(self, grit: str | None = None) -> PrestonFit:
        """The fit of ``grit`` (may be omitted when there is only one)."""
        if grit is None:
            if len(self.fits) == 1:
                return next(iter(self.fits.values()))
            raise InputError(f"the calibration has grits {', '.join(self.fits)}; choose one (--grit)")
        try:
            return self.fits[str(grit)]
        except KeyError:
            raise InputError(f"no calibration for grit {grit!r}; it has {', '.join(self.fits)}") from None


def calibrate(trials, *, fit_exponents: bool = False, error_model: str = "relative", confidence: float = 0.9,
              pad_radius: float = 0.0381) -> Calibration:
    """Fit the Preston coefficient (per grit) from trials.

    Parameters
    ----------
    trials : Trials, or str / Path of a trials CSV
    fit_exponents : bool
        Also fit the exponents of pressure and speed (``d ∝ p^a v^b``) by least squares on ``log d``;
        needs at least 4 trials per grit with at least 2 distinct pressures and 2 distinct speeds.
    error_model : str
        ``"relative"`` (default) or ``"absolute"``: how the measurement error scales (module
        docstring); ignored with ``fit_exponents`` (log-model, i.e. relative errors).
    confidence : float
        Level of the intervals, in (0, 1) (default 0.9).
    pad_radius : float
        Pad radius (m) for CSV rows without ``pad_radius_m``.

    Returns
    -------
    Calibration
    """
    if not isinstance(trials, Trials):
        source = str(trials)
        trials = read_trials(trials, pad_radius=pad_radius)
    else:
        source = "arrays"
    if error_model not in ("relative", "absolute"):
        raise InputError(f"error_model must be 'relative' or 'absolute', got {error_model!r}")
    if not (0 < confidence < 1):
        raise InputError(f"confidence must lie in (0, 1), got {confidence!r}")
    fits = {}
    for grit in sorted(set(trials.grit.tolist()), key=_grit_key):
        sub = trials.subset(trials.grit == grit)
        aged = bool(np.all(np.isfinite(sub.pad_age))) and len(np.unique(np.round(sub.pad_age, 6))) >= 2
        if fit_exponents:
            if aged:
                log.warning("grit %s: pad_age_s is ignored when the exponents are fitted (no wear fit)", grit)
            fits[grit] = _fit_log(sub, grit, confidence)
        elif aged:
            fits[grit] = _fit_wear(sub, grit, confidence)
        else:
            fits[grit] = _fit_linear(sub, grit, confidence, error_model)
    meta = {"source": source, "n_trials": len(trials), "fit_exponents": bool(fit_exponents),
            "error_model": "log" if fit_exponents else error_model, "confidence": confidence,
            "tool": trials_tool_record(trials)}
    return Calibration(fits, meta)


def trials_tool_record(trials: Trials) -> dict:
    """The tool the trials were run with, for the calibration file (units in the key names).

    ``motion`` is ``"orbital"`` (every trial has an orbit radius), ``"rotary"`` (none has) or
    ``"mixed"``; the speeds, orbits and pad radii are the distinct values met; force and feed their
    ranges."""
    orbital = trials.orbit_radius > 0
    motion = "orbital" if orbital.all() else "rotary" if not orbital.any() else "mixed"
    uniq = lambda a: sorted({round(float(v), 12) for v in a})
    return {"motion": motion,
            "spindle_speed_rpm": uniq(trials.omega * 60.0 / (2 * math.pi)),
            "orbit_radius_m": uniq(trials.orbit_radius[orbital]) if orbital.any() else [],
            "pad_radius_m": uniq(trials.pad_radius),
            "force_N": [float(trials.force.min()), float(trials.force.max())],
            "feed_m_per_s": [float(trials.feed.min()), float(trials.feed.max())],
            "pad_age_s": ([float(np.nanmin(trials.pad_age)), float(np.nanmax(trials.pad_age))]
                          if np.isfinite(trials.pad_age).any() else None)}


def _grit_key(g: str):
    try:
        return (0, float(g), g)
    except ValueError:
        return (1, 0.0, g)


def _fit_linear(t: Trials, grit: str, level: float, model: str) -> PrestonFit:
    from scipy import stats

    n = len(t)
    if n < 2:
        raise InputError(f"grit {grit}: need at least 2 measured trials to give an interval, got {n}")
    X, d = exposure(t), t.depth
    tq = stats.t.ppf(0.5 + level / 2, n - 1)
    if model == "relative":
        ki = d / X
        k = float(ki.mean())
        s_rel = float(ki.std(ddof=1) / k)
        se = float(ki.std(ddof=1) / math.sqrt(n))
        resid = s_rel
    else:
        k = float(X @ d / (X @ X))
        s = math.sqrt(float(np.sum((d - k * X) ** 2)) / (n - 1))
        se = s / math.sqrt(float(X @ X))
        resid = s
    return PrestonFit(grit, k, k - tq * se, k + tq * se, level, n_trials=n, error_model=model, residual_std=resid,
                      dof=n - 1, covariance=((se * se,),), hardness=_mean_hardness(t))


def _fit_wear(t: Trials, grit: str, level: float) -> PrestonFit:
    """Fresh-media ``k_p0`` and wear rate ``λ`` from ``log(d / X) = log k_p0 − λ a`` (module docstring)."""
    from scipy import stats

    n = len(t)
    if n < 3:
        raise InputError(f"grit {grit}: fitting the pad wear needs at least 3 measured trials, got {n}")
    y = np.log(t.depth / exposure(t))
    A = np.column_stack([np.ones(n), -t.pad_age])
    theta, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ theta
    dof = n - 2
    s2 = float(r @ r) / dof
    cov = s2 * np.linalg.inv(A.T @ A)
    tq = stats.t.ppf(0.5 + level / 2, dof)
    se = np.sqrt(np.diag(cov))
    k = math.exp(theta[0])
    return PrestonFit(grit, k, math.exp(theta[0] - tq * se[0]), math.exp(theta[0] + tq * se[0]), level,
                      n_trials=n, error_model="wear", residual_std=math.sqrt(s2), dof=dof,
                      covariance=tuple(map(tuple, cov.tolist())), hardness=_mean_hardness(t),
                      wear_rate=float(theta[1]),
                      wear_rate_interval=(float(theta[1] - tq * se[1]), float(theta[1] + tq * se[1])))


def _fit_log(t: Trials, grit: str, level: float) -> PrestonFit:
    from scipy import optimize, stats

    n = len(t)
    if n < 4:
        raise InputError(f"grit {grit}: fitting the exponents needs at least 4 measured trials, got {n}")
    speed = np.where(t.orbit_radius > 0, t.omega * t.orbit_radius, t.omega * t.pad_radius)
    if len(np.unique(np.round(t.pressure, 9))) < 2 or len(np.unique(np.round(speed, 9))) < 2:
        raise InputError(f"grit {grit}: fitting the exponents needs at least 2 distinct forces (pressures) and 2 "
                         "distinct spindle speeds; vary them in the trials (see `swath doe`) or fit without exponents")
    y = np.log(t.depth)
    k0 = float(np.mean(t.depth / exposure(t)))
    res = optimize.least_squares(lambda th: _log_model(th, t) - y, x0=[math.log(k0), 1.0, 1.0],
                                 bounds=([-np.inf, -5.0, -0.9], [np.inf, 5.0, 5.0]))
    theta = res.x
    r = _log_model(theta, t) - y
    dof = n - 3
    s2 = float(r @ r) / dof if dof > 0 else math.nan
    J = _jacobian(theta, t)
    cov = s2 * np.linalg.pinv(J.T @ J)
    tq = stats.t.ppf(0.5 + level / 2, dof) if dof > 0 else math.inf
    se = np.sqrt(np.diag(cov))
    k = math.exp(theta[0])
    return PrestonFit(grit, k, math.exp(theta[0] - tq * se[0]), math.exp(theta[0] + tq * se[0]), level,
                      pressure_exponent=float(theta[1]), speed_exponent=float(theta[2]),
                      pressure_exponent_interval=(float(theta[1] - tq * se[1]), float(theta[1] + tq * se[1])),
                      speed_exponent_interval=(float(theta[2] - tq * se[2]), float(theta[2] + tq * se[2])),
                      n_trials=n, error_model="log", residual_std=math.sqrt(s2), dof=dof,
                      covariance=tuple(map(tuple, cov.tolist())), hardness=_mean_hardness(t))


def _mean_hardness(t: Trials) -> float:
    h = t.hardness[np.isfinite(t.hardness)]
    return float(h.mean()) if len(h) else math.nan


# ----------------------------------------------------------------------------------------------
# Calibration file
# ----------------------------------------------------------------------------------------------
def _finite(x):
    return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x


def calibration_to_json(cal: Calibration) -> dict:
    """The calibration as a JSON-ready dict (units in the key names)."""
    fits = []
    for f in cal.fits.values():
        entry = {"grit": f.grit}
        if f.linear:
            entry.update(preston_coefficient_per_pa=f.preston, preston_coefficient_low_per_pa=f.preston_low,
                         preston_coefficient_high_per_pa=f.preston_high)
        else:
            entry.update(preston_coefficient_si=f.preston, preston_coefficient_low_si=f.preston_low,
                         preston_coefficient_high_si=f.preston_high,
                         preston_coefficient_unit="m / (Pa^a * (m/s)^b * s)")
        entry.update(
            confidence=f.confidence, pressure_exponent=f.pressure_exponent, speed_exponent=f.speed_exponent,
            pressure_exponent_interval=[_finite(v) for v in f.pressure_exponent_interval],
            speed_exponent_interval=[_finite(v) for v in f.speed_exponent_interval],
            n_trials=f.n_trials, error_model=f.error_model, dof=f.dof,
            covariance=[list(r) for r in f.covariance],
            **({"residual_std_m": f.residual_std} if f.error_model == "absolute"
               else {"residual_std_relative": f.residual_std}),
            hardness_pa=_finite(f.hardness),
            archard_wear_coefficient_m3_per_n_m=f.preston if f.linear else None,
            archard_coefficient=_finite(f.archard_coefficient),
            wear_rate_per_s=f.wear_rate, wear_rate_interval_per_s=[_finite(v) for v in f.wear_rate_interval],
        )
        fits.append(entry)
    return {"format": CALIBRATION_FORMAT, "version": 1, "metadata": cal.metadata, "fits": fits}


def write_calibration(path, cal: Calibration) -> Path:
    """Write the calibration JSON atomically; returns the path."""
    path = Path(path)
    write_text_atomic(path, json.dumps(calibration_to_json(cal), indent=2, allow_nan=False) + "\n")
    return path


def load_calibration(path) -> Calibration:
    """Read a calibration file written by :func:`write_calibration`."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read calibration {path}: {exc}") from exc
    if not isinstance(data, dict) or data.get("format") != CALIBRATION_FORMAT:
        raise InputError(f"{path} is not a swath calibration file (expected \"format\": \"{CALIBRATION_FORMAT}\"); "
                         "make one with `swath calibrate trials.csv`")
    fits = {}
    nan = lambda v: math.nan if v is None else float(v)
    try:
        for e in data["fits"]:
            sfx = "per_pa" if "preston_coefficient_per_pa" in e else "si"
            fits[str(e["grit"])] = PrestonFit(
                str(e["grit"]), float(e[f"preston_coefficient_{sfx}"]), float(e[f"preston_coefficient_low_{sfx}"]),
                float(e[f"preston_coefficient_high_{sfx}"]), float(e["confidence"]),
                pressure_exponent=float(e["pressure_exponent"]), speed_exponent=float(e["speed_exponent"]),
                pressure_exponent_interval=tuple(nan(v) for v in e["pressure_exponent_interval"]),
                speed_exponent_interval=tuple(nan(v) for v in e["speed_exponent_interval"]),
                n_trials=int(e["n_trials"]), error_model=str(e["error_model"]), dof=int(e["dof"]),
                covariance=tuple(tuple(float(x) for x in r) for r in e["covariance"]),
                residual_std=float(e.get("residual_std_m", e.get("residual_std_relative", math.nan))),
                hardness=nan(e.get("hardness_pa")), wear_rate=float(e.get("wear_rate_per_s", 0.0)),
                wear_rate_interval=tuple(nan(v) for v in e.get("wear_rate_interval_per_s", [None, None])))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"calibration {path} is malformed: {exc!r}") from exc
    if not fits or any(not (f.preston > 0) for f in fits.values()):
        raise InputError(f"calibration {path} has no positive Preston coefficient")
    return Calibration(fits, dict(data.get("metadata", {})))
