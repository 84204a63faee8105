"""Figures from the decimated traces of seed 0 of each variant."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import LogFormatterSciNotation

from marinebench.config import Experiment, FigureSpec

UNITS = {"depth": "m", "yaw": "rad", "tau_depth": "N", "tau_yaw": "N m", "u": "m/s", "v": "m/s", "r": "rad/s", "sigma_u": "m/s²", "sigma_v": "m/s²", "sigma_r": "rad/s²",
         "x": "m", "y": "m", "psi": "rad", "b_x": "N", "b_y": "N", "b_n": "N m", "depth_rate": "m/s", "yaw_rate": "rad/s",
         "depth_disturbance": "m/s²", "yaw_disturbance": "rad/s²"}
UNITS |= {f"{s}_{of}": UNITS[s] for s in ("depth", "yaw", "depth_disturbance", "yaw_disturbance") for of in ("cdo", "eo")}
UNITS |= {f"{s}_meas": UNITS[s] for s in ("depth", "yaw")}
NAMES = {"u": "surge u", "v": "sway v", "r": "yaw rate r", "sigma_u": "σ_u", "sigma_v": "σ_v", "sigma_r": "σ_r",
         "x": "north x", "y": "east y", "psi": "heading ψ", "b_x": "bias b_N", "b_y": "bias b_E", "b_n": "bias b_ψ"}


#: Title size (points) and resolution (dpi) of every figure marinebench writes.
TITLE_SIZE, DPI = 10, 110


def save(fig, title: str, path: Path) -> None:
    """Title ``fig``, lay it out, write it to ``path`` and close it. Each line of ``title`` is wrapped to the
    figure's width (at about 0.6 em a character), so a long model label such as ``supply_shipx_lf (observers:
    supply_dp_linear)`` is not cut off at both edges of a one-column figure, and the panels are laid out below it."""
    chars = int(fig.get_figwidth() * 72 / (0.6 * TITLE_SIZE))
    text = fig.suptitle("\n".join(textwrap.fill(line, chars) for line in title.split("\n")), fontsize=TITLE_SIZE)
    fig.tight_layout()
    renderer = fig.canvas.get_renderer()  # tight_layout alone let a tall figure's three-line title overlap its top panel
    boxes = [box for ax in fig.axes if (box := ax.get_tightbbox(renderer)) is not None]  # None: a hidden panel
    overlap = max((box.y1 for box in boxes), default=0.0) - text.get_window_extent(renderer).y0
    if overlap > 0:
        fig.subplots_adjust(top=fig.subplotpars.top - (overlap + 6) / fig.bbox.height)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


class PlainLog(LogFormatterSciNotation):
    """A log axis's ticks labelled where matplotlib labels them, but as plain numbers: 4, not 4×10⁰."""

    def __call__(self, value, pos=None):
        return f"{value:.3g}" if super().__call__(value, pos) else ""


def plain_log_labels(axis) -> None:
    """Label a log ``axis`` (``ax.xaxis``, a colour bar's ``yaxis``) in plain numbers where matplotlib would label it."""
    axis.set_major_formatter(PlainLog())
    axis.set_minor_formatter(PlainLog(labelOnlyBase=False))


def traces_needed(spec: FigureSpec) -> tuple[list[str], list[str]]:
    """The traced signals a figure draws: those it needs a truth of, and those it needs an estimate of (a tracking
    figure draws the reference ``<signal>_ref`` and the control input ``tau_<signal>``, both of the world's truth)."""
    if spec.kind == "tracking":
        return [*spec.signals, *(f"{s}_ref" for s in spec.signals), *(f"tau_{s}" for s in spec.signals)], []
    return list(spec.signals), []


def seed0_runs(exp: Experiment, spec: FigureSpec, run_variant, run_seed) -> tuple[list[str], dict[str, str], list[int]]:
    """The figure's variant names, their legend labels, and the batch index of each one's seed-0 run."""
    names = spec.variants or [v.name for v in exp.variants]
    index = {v.name: i for i, v in enumerate(exp.variants)}
    labels = {v.name: v.label or v.name for v in exp.variants}
    runs = [int(np.flatnonzero((run_variant == index[n]) & (run_seed == 0))[0]) for n in names]
    return names, labels, runs


def _autoscale(ax, series: list[np.ndarray], late) -> None:
    """Fit the y axis to the series' finite values at the ``late`` samples (after the start-up transient)."""
    data = np.concatenate([x[late] for x in series])
    data = data[np.isfinite(data)]
    if data.size:
        lo, hi = data.min(), data.max()
        pad = 0.1 * (hi - lo) or 1e-12
        ax.set_ylim(lo - pad, hi + pad)


def _actual_and_estimates(ax, t, mask, truth: np.ndarray, est: np.ndarray, curves: list[tuple[str, int]]) -> list[np.ndarray]:
    """One signal's row: the actual trajectory, one black line when the variants' runs share it (an open-loop world,
    or observers watching one closed loop), else each variant's own, dashed in its colour (estimates that steer the
    vehicle apart); and each variant's estimate. Returns the series the axis is scaled to."""
    runs = [b for _, b in curves]
    own = any(not np.array_equal(truth[:, b], truth[:, runs[0]], equal_nan=True) for b in runs)
    if not own:
        ax.plot(t[mask], truth[mask, runs[0]], "k-", lw=1.6, label="actual")
    for label, b in curves:
        (line,) = ax.plot(t[mask], est[mask, b], lw=1.0, label=label)
        if own:
            ax.plot(t[mask], truth[mask, b], "--", color=line.get_color(), lw=1.2, label=f"actual ({label})")
    return [truth[:, b] for b in (runs if own else runs[:1])] + [est[:, b] for b in runs]


def timeseries(exp: Experiment, spec: FigureSpec, t, truth, est, run_variant, run_seed, path: Path) -> None:
    """A row per signal (and one of its errors below it with ``spec.error``): the actual trajectory (each variant's
    own, dashed, where the variants' runs of seed 0 differ, as in a closed loop steered by different estimates) and
    each variant's estimate, or, for a world signal with no estimate (a control input), each variant's."""
    names, labels, runs = seed0_runs(exp, spec, run_variant, run_seed)
    rows = len(spec.signals) * (2 if spec.error else 1)
    fig, axes = plt.subplots(rows, 1, figsize=(8, 2.4 * rows), sharex=True, squeeze=False)
    axes = axes[:, 0]
    mask = slice(None)
    if spec.t_range is not None:
        mask = (t >= spec.t_range[0]) & (t <= spec.t_range[1])
    after = spec.ylim_after if spec.ylim_after is not None else getattr(exp.metrics[0], "t_start", 0.0)
    late = (t >= after) if spec.t_range is None else (t >= after) & mask
    curves = [(labels[name], b) for name, b in zip(names, runs)]
    for i, sig in enumerate(spec.signals):
        ax = axes[i * (2 if spec.error else 1)]
        if sig in est:  # truth ("actual") and each variant's estimate (or reference)
            series = _actual_and_estimates(ax, t, mask, truth[sig], est[sig], curves)
            if spec.error:
                for label, b in curves:
                    axes[i * 2 + 1].plot(t[mask], truth[sig][mask, b] - est[sig][mask, b], lw=1.0, label=label)
                _autoscale(axes[i * 2 + 1], [truth[sig][:, b] - est[sig][:, b] for b in runs], late)
        else:  # a world signal with no estimate (e.g. a control input): one curve per variant
            series = [truth[sig][:, b] for b in runs]
            for label, b in curves:
                ax.plot(t[mask], truth[sig][mask, b], lw=1.0, label=label)
        _autoscale(ax, series, late)
        ax.set_ylabel(f"{NAMES.get(sig, sig)} [{UNITS.get(sig, '-')}]")
        ax.legend(loc="best", fontsize=7)
        if spec.error:
            axes[i * 2 + 1].set_ylabel(f"error [{UNITS.get(sig, '-')}]")
            axes[i * 2 + 1].axhline(0, color="k", lw=0.5)
    axes[-1].set_xlabel("time [s]")
    save(fig, f"{spec.title or spec.file}\n(y axes scaled to t ≥ {after:g} s; seed 0; model {exp.model_label()})", path)


def tracking(exp: Experiment, spec: FigureSpec, t, truth, est, run_variant, run_seed, path: Path) -> None:
    """Closed-loop layout of Tijjani Figs 3/5/7/9: a column per DOF (signals), rows: the reference and each
    variant's actual trajectory, the tracking errors (the reference less the truth, also for a variant that reports
    an observer's estimate), the control inputs ``tau_<signal>``. Yaw in degrees."""
    names, labels, runs = seed0_runs(exp, spec, run_variant, run_seed)
    mask = slice(None) if spec.t_range is None else (t >= spec.t_range[0]) & (t <= spec.t_range[1])
    cols = len(spec.signals)
    fig, axes = plt.subplots(3, cols, figsize=(5.5 * cols, 7.5), sharex=True, squeeze=False)
    for j, sig in enumerate(spec.signals):
        k = np.rad2deg(1.0) if sig == "yaw" else 1.0
        unit = "deg" if sig == "yaw" else UNITS.get(sig, "-")
        top, mid, bottom = axes[:, j]
        ref = truth[f"{sig}_ref"]
        top.plot(t[mask], k * ref[mask, runs[0]], "k--", lw=1.4, label="desired")
        for name, b in zip(names, runs):
            top.plot(t[mask], k * truth[sig][mask, b], lw=1.0, label=labels[name])
            mid.plot(t[mask], k * (ref[mask, b] - truth[sig][mask, b]), lw=1.0, label=labels[name])
            bottom.plot(t[mask], truth[f"tau_{sig}"][mask, b], lw=0.8, label=labels[name])
        top.set_ylabel(f"{sig} [{unit}]")
        mid.set_ylabel(f"error [{unit}]")
        mid.axhline(0, color="k", lw=0.5)
        bottom.set_ylabel(f"tau_{sig} [{UNITS.get(f'tau_{sig}', '-')}]")
        bottom.set_xlabel("time [s]")
        for ax in (top, mid, bottom):
            ax.legend(loc="best", fontsize=7)
    save(fig, f"{spec.title or spec.file} (seed 0, model {exp.model_label()})", path)
