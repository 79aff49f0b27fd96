"""One window through the whole chain: gate → (EMD → IMF pruning | band-pass) → IF → DNL → verdict.

Two methods, chosen by :attr:`DiagnosisConfig.method`:

``robust`` (default): set-point changes → analyse the control error; gate; data-quality
guards; then the DNL of the phase-locked mean wave with a surrogate significance test
(:mod:`pipeline.robust`), on the analysed signal and, when given, on the OP as well; verdict
``nonlinear`` when the DNL is both significant (p <= alpha) and large (>= min_dnl), ``linear``
when it is not significant or smaller than a sticking valve makes, ``uncertain`` when the
significance is borderline (alpha < p <= 2 alpha with a large DNL) or a data-quality guard
fails.  When the analysed signal does not pass the gate but the OP does, the OP's period is
used.  A window that does not oscillate is searched for stick-slip episodes
(:mod:`pipeline.stickslip`: a Hammerstein stiction model of OP → PV against a linear one)
when PV, OP and SP are known.

``paper``: the method of Aftab, Hovd, Huang & Sivalingam (2016) as published:
a window that oscillates (Thornhill et al. 2003 gate, :mod:`pipeline.gate`) is decomposed by
bounded EMD (:mod:`pipeline.emd`), spurious IMFs are pruned by ``lambda > 0.5`` (eq. 7–8), the DNL
of every kept IMF (eq. 11) and the energy-weighted TDNL (eq. 12) are computed, and the verdict
follows Table 1: ``TDNL > threshold`` (0.1) → non-linear cause, else linear cause.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from .dnl import imf_dnl, tdnl
from .emd import EMDConfig, emd
from .errors import PipelineConfigError, SignalError
from .frequency import instantaneous_frequency
from .gate import GateConfig, GateResult, detrend_linear, oscillation_gate
from .pruning import significant_imfs
from .quality import frozen_pv, window_guards
from .robust import RobustConfig, RobustResult, robust_dnl_test
from .stickslip import StickSlip, stick_slip_episodes

__all__ = ["Verdict", "DiagnosisConfig", "WindowDiagnosis", "diagnose_window", "fill_gaps"]

Verdict = Literal["nonlinear", "linear", "uncertain", "not_oscillating", "invalid"]
Method = Literal["robust", "paper"]


@dataclass(frozen=True)
class DiagnosisConfig:
    """Settings of the whole chain.

    Parameters
    ----------
    method : ``robust`` (default) or ``paper`` (Aftab et al. 2016 taken literally).
    gate : oscillation-gate thresholds.
    emd : sifting budget and IMF cap (paper method).
    robust : settings of the robust test.
    lambda_threshold : keep IMFs with ``lambda_i`` above this (eq. 8; paper 0.5).
    end_trim_waves : full waves dropped at each end of every IMF before the DNL statistic.
    threshold : TDNL above which the cause is non-linear (Table 1; paper 0.1).
    max_missing_fraction : most missing (NaN) samples a window may have; they are filled by
        linear interpolation.  More → verdict ``invalid``.
    max_gap_samples : longest run of missing samples that may be filled.
    """

    method: Method = "robust"
    gate: GateConfig = field(default_factory=GateConfig)
    emd: EMDConfig = field(default_factory=EMDConfig)
    robust: RobustConfig = field(default_factory=RobustConfig)
    lambda_threshold: float = 0.5
    end_trim_waves: int = 1
    threshold: float = 0.1
    max_missing_fraction: float = 0.05
    max_gap_samples: int = 5

    def __post_init__(self) -> None:
        if self.method not in ("robust", "paper"):
            raise PipelineConfigError(f"method={self.method!r} must be 'robust' or 'paper'")
        if not 0 <= self.lambda_threshold < 1:
            raise PipelineConfigError(
                f"lambda_threshold={self.lambda_threshold!r} must be in [0, 1): at 1 no IMF would be kept"
            )
        if self.end_trim_waves < 0:
            raise PipelineConfigError(f"end_trim_waves={self.end_trim_waves!r} must be >= 0")
        if not self.threshold > 0:
            raise PipelineConfigError(
                f"threshold={self.threshold!r} must be > 0, or every oscillation would be called non-linear"
            )
        if not 0 <= self.max_missing_fraction < 1:
            raise PipelineConfigError(f"max_missing_fraction={self.max_missing_fraction!r} must be in [0, 1)")
        if self.max_gap_samples < 0:
            raise PipelineConfigError(f"max_gap_samples={self.max_gap_samples!r} must be >= 0")

    @property
    def decision_threshold(self) -> float:
        """The figure a window's ``tdnl`` must exceed to read non-linear: the TDNL threshold
        (paper method, Table 1) or the least mean-wave DNL of the robust method."""
        return self.robust.min_dnl if self.method == "robust" else self.threshold

    def with_decision_threshold(self, value: float) -> "DiagnosisConfig":
        """A copy whose :attr:`decision_threshold` is ``value`` (for the method in use)."""
        if self.method == "robust":
            return replace(self, robust=replace(self.robust, min_dnl=value))
        return replace(self, threshold=value)


@dataclass(frozen=True)
class WindowDiagnosis:
    """Verdict on one window, with the figures behind it.

    Paper method: ``imfs_kept`` are 1-based IMF numbers (IMF 1 has the highest frequency),
    ``dnl`` the DNL of each kept IMF in the same order, ``lambdas`` the eq. 8 figure of every IMF.
    Robust method: ``dnl`` holds the one DNL of the band-passed oscillation component (also in
    ``tdnl``), ``robust`` the surrogate threshold and p-value; no IMFs.  ``stick_slip`` holds
    the stuck-valve episodes found in a window that does not oscillate (PV, OP and SP known).
    """

    verdict: Verdict
    reason: str
    gate: GateResult | None = None
    imfs_kept: tuple[int, ...] = ()
    dnl: tuple[float, ...] = ()
    tdnl: float = float("nan")
    lambdas: tuple[float, ...] = ()
    imf_frequencies_hz: tuple[float, ...] = ()
    n_filled: int = 0
    method: Method = "paper"
    robust: RobustResult | None = None
    guards: tuple[str, ...] = ()
    stick_slip: StickSlip | None = None


def fill_gaps(x: np.ndarray, *, max_fraction: float, max_gap: int) -> tuple[np.ndarray, int, str | None]:
    """Fill missing (NaN) samples by linear interpolation when there are few and short gaps.

    Returns
    -------
    (filled, n_missing, problem): ``problem`` is ``None`` when the window is usable, else a
    sentence saying why not (and ``filled`` is the input unchanged).
    """
    x = np.asarray(x, dtype=np.float64)
    bad = ~np.isfinite(x)
    n_bad = int(bad.sum())
    if n_bad == 0:
        return x, 0, None
    if n_bad > max_fraction * x.size:
        return x, n_bad, f"{n_bad} of {x.size} samples missing (more than {max_fraction:.0%})"
    edges = np.diff(np.r_[0, bad.astype(np.int8), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    if runs.max() > max_gap:
        return x, n_bad, f"a gap of {int(runs.max())} missing samples (longest fillable {max_gap})"
    if bad[0] or bad[-1]:
        return x, n_bad, "missing samples at the window's edge"
    idx = np.arange(x.size)
    filled = x.copy()
    filled[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return filled, n_bad, None


def diagnose_window(
    x: np.ndarray,
    *,
    fs: float,
    config: DiagnosisConfig = DiagnosisConfig(),
    op: np.ndarray | None = None,
    mode: np.ndarray | None = None,
    sp: np.ndarray | None = None,
    stick_slip: bool = True,
) -> WindowDiagnosis:
    """Diagnose the cause of oscillation in one window of a loop signal.

    Parameters
    ----------
    x : 1-D window (PV, OP or control error) on a regular grid; NaN marks a missing sample.
    fs : sampling frequency in Hz.
    config : see :class:`DiagnosisConfig` (``method`` selects robust or paper).
    op : the controller output over the same window, when known: saturation guard, and (robust
        method) a second witness of the non-linearity.
    mode : the loop's mode over the same window, when known (1 = automatic).  A window with a
        sample in another mode is ``invalid``: a loop in manual cannot show a control-loop
        oscillation.
    sp : the set point over the same window when ``x`` is the PV (robust method).  When it
        changes inside the window, the control error ``sp - x`` is analysed instead of the PV
        (a set-point step in the PV is a transient, not an oscillation, and its corners would
        read as intra-wave frequency modulation); the reason says so.  A PV frozen to the bit while
        the OP moves is noted in the reason (robust method; :func:`pipeline.quality.frozen_pv`).
    stick_slip : search a window that does not oscillate for stick-slip episodes (needs ``op``
        and ``sp``; the costliest step of a non-oscillating window).  A caller sliding
        overlapping windows may search only some of them (the monitor: one per window length).

    Returns
    -------
    WindowDiagnosis; ``verdict`` is ``invalid`` when the window cannot be analysed (the reason
    says why), ``not_oscillating`` when the gate rejects it (EMD is then not run).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise SignalError(f"diagnose_window expects a 1-D window, got shape {x.shape}")
    if not fs > 0:
        raise SignalError(f"fs={fs!r} must be > 0")
    if mode is not None:
        manual = int(np.count_nonzero(np.isfinite(mode) & (mode != 1)))
        if manual:
            return WindowDiagnosis("invalid", f"loop not in automatic for {manual} of {x.size} samples")
    notes: list[str] = []
    pv = x
    frozen = frozen_pv(x, np.asarray(op, dtype=np.float64)) if config.method == "robust" and op is not None else None
    if frozen:
        notes.append(frozen)
    if config.method == "robust" and sp is not None:
        sp = np.asarray(sp, dtype=np.float64)
        change = _setpoint_change(sp, x)
        if change:
            x = sp - x
            notes.append(f"{change}: analysing the control error sp - pv")
    x, n_filled, problem = fill_gaps(x, max_fraction=config.max_missing_fraction, max_gap=config.max_gap_samples)
    if problem:
        return WindowDiagnosis("invalid", problem, n_filled=n_filled)
    gate = oscillation_gate(x, fs=fs, config=config.gate)
    if config.method == "robust":
        diag = _diagnose_robust(x, fs=fs, config=config, gate=gate, n_filled=n_filled, op=op, notes=notes)
        if stick_slip and diag.verdict == "not_oscillating" and op is not None and sp is not None:  # x is the PV
            diag = _with_stick_slip(diag, pv, op, config, sp=sp)
        return diag
    if not gate.oscillating:
        return WindowDiagnosis("not_oscillating", gate.reason, gate, n_filled=n_filled)

    y = detrend_linear(x)
    imfs, _ = emd(y, config=config.emd)
    if imfs.shape[0] == 0:
        return WindowDiagnosis("invalid", "EMD found no oscillatory mode", gate, n_filled=n_filled)
    keep, lam = significant_imfs(imfs, y, threshold=config.lambda_threshold)
    if keep.size == 0:
        return WindowDiagnosis("invalid", "no IMF correlates with the signal", gate,
                               lambdas=tuple(map(float, lam)), n_filled=n_filled)
    kept = imfs[keep]
    freq, _ = instantaneous_frequency(kept, fs=fs)
    figs = [imf_dnl(c, fs=fs, end_trim_waves=config.end_trim_waves, freq=f) for c, f in zip(kept, freq)]
    dnl = np.array([f.dnl for f in figs])
    total = tdnl(dnl, kept)
    common = dict(
        gate=gate,
        imfs_kept=tuple(int(i) + 1 for i in keep),
        dnl=tuple(float(d) for d in dnl),
        tdnl=total,
        lambdas=tuple(float(v) for v in lam),
        imf_frequencies_hz=tuple(f.mean_frequency_hz for f in figs),
        n_filled=n_filled,
    )
    imf_list = ", ".join(f"IMF{i}" for i in common["imfs_kept"])
    if not np.isfinite(total):
        return WindowDiagnosis("invalid", f"no kept IMF ({imf_list}) has a full wave to measure", **common)
    if total > config.threshold:
        reason = (f"TDNL {total:.3f} > {config.threshold:g} over {imf_list}: intra-wave frequency modulation, "
                  f"non-linear cause (e.g. valve stiction)")
        return WindowDiagnosis("nonlinear", reason, **common)
    reason = (f"TDNL {total:.3f} <= {config.threshold:g} over {imf_list}: no intra-wave frequency modulation, "
              f"linear cause (tuning or disturbance)")
    return WindowDiagnosis("linear", reason, **common)


def _setpoint_change(sp: np.ndarray, pv: np.ndarray) -> str | None:
    """A sentence when the set point moves inside the window by more than rounding, else None."""
    ok = np.isfinite(sp)
    if ok.sum() < 2:
        return None
    span = float(np.ptp(sp[ok]))
    scale = max(float(np.nanmax(np.abs(sp[ok]))), float(np.nanstd(pv)) if np.isfinite(pv).any() else 0.0, 1e-300)
    if span <= 1e-9 * scale:
        return None
    return f"set point changes inside the window (range {span:.4g})"


def _usable_op(op: np.ndarray | None, x: np.ndarray, config: DiagnosisConfig) -> np.ndarray | None:
    """The OP as a detrended second witness, when it has the window's length, few gaps and is
    not the analysed series itself."""
    if op is None:
        return None
    op = np.asarray(op, dtype=np.float64)
    if op.shape != x.shape or np.array_equal(op, x, equal_nan=True):
        return None
    filled, _, problem = fill_gaps(op, max_fraction=config.max_missing_fraction, max_gap=config.max_gap_samples)
    if problem or np.ptp(filled) == 0:
        return None
    return detrend_linear(filled)


def _with_stick_slip(diag: WindowDiagnosis, pv, op, config: DiagnosisConfig, *, sp) -> WindowDiagnosis:
    """Add the stuck-valve episodes (:mod:`pipeline.stickslip`) to a non-oscillating window
    whose PV, OP and SP are known."""
    series = []
    for v in (pv, op, sp):
        v = np.asarray(v, dtype=np.float64)
        if v.shape != np.shape(pv):
            return diag
        filled, _, problem = fill_gaps(v, max_fraction=config.max_missing_fraction, max_gap=config.max_gap_samples)
        if problem:
            return diag
        series.append(filled)
    found = stick_slip_episodes(*series)
    if found is None or not found.episodes:
        return replace(diag, stick_slip=found)
    return replace(diag, stick_slip=found, reason=f"{diag.reason}; {found.reason}")


def _diagnose_robust(x, *, fs, config, gate, n_filled, op, notes) -> WindowDiagnosis:
    guards = tuple(window_guards(x, op=op))
    note = ("; " + "; ".join(notes + list(guards))) if notes or guards else ""
    common = dict(gate=gate, n_filled=n_filled, method="robust", guards=guards)
    witness = _usable_op(op, x, config)
    if not gate.oscillating and witness is not None:
        # the loop oscillates if its OP does: a slow process can blur the PV's limit cycle
        op_gate = oscillation_gate(witness, fs=fs, config=config.gate)
        if op_gate.oscillating:
            gate = op_gate
            common["gate"] = gate
            note = f"; the analysed signal alone does not pass the gate, the OP does ({op_gate.reason})" + note
    if not gate.oscillating:
        return WindowDiagnosis("not_oscillating", gate.reason + note, **common)
    rc = config.robust
    r = robust_dnl_test(detrend_linear(x), fs=fs, period_s=gate.period_s, config=rc, other=witness)
    common.update(dnl=(r.dnl,), tdnl=r.dnl, robust=r)
    if not np.isfinite(r.p_value):
        return WindowDiagnosis("invalid", "the oscillation has no full wave to measure" + note, **common)
    where = " (OP)" if r.signal == "other" else ""
    figures = (f"DNL of the mean wave{where} {r.dnl:.3f} vs {r.threshold:.3f} for a linear oscillation "
               f"(95 % of {r.n_surrogates} surrogates), p = {r.p_value:.3f}")
    significant, large = r.p_value <= rc.alpha, r.dnl >= rc.min_dnl
    if significant and large:
        if guards:
            return WindowDiagnosis("uncertain", f"{figures}: would be non-linear, but{note[1:]}", **common)
        return WindowDiagnosis("nonlinear", f"{figures}: phase-locked intra-wave frequency modulation, "
                               f"non-linear cause (e.g. valve stiction){note}", **common)
    if significant:
        return WindowDiagnosis("linear", f"{figures}: a phase-locked distortion, but smaller than a sticking valve "
                               f"makes (< {rc.min_dnl:g}): linear cause (tuning or disturbance){note}", **common)
    if large and r.p_value <= 2 * rc.alpha:
        return WindowDiagnosis("uncertain", f"{figures}: borderline significance{note}", **common)
    return WindowDiagnosis("linear", f"{figures}: no more intra-wave modulation than a linear oscillation, "
                           f"linear cause (tuning or disturbance){note}", **common)
