"""Figures of a sweep: learning curves with confidence bands, and final-score intervals.

Both read the per-config dicts of :func:`agents.stats.aggregate`. The interval plot follows the
layout of rliable's ``plot_interval_estimates`` (Agarwal et al., 2021): one panel per aggregate,
one row per config, a bar for the 95 % bootstrap interval and a tick at the point estimate.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rigid_env.files import atomic_open  # noqa: E402

METRICS = (("mean_return", "evaluation return", 1.0), ("success_rate", "success rate (%)", 100.0))


def config_label(entry: dict) -> str:
    """``n_epochs=1, gamma=0.98`` or ``config file`` when nothing was changed."""
    config = entry["config"]
    if not config:
        return "config file"
    return ", ".join(f"{k}={_short(v)}" for k, v in sorted(config.items()))


def _short(value: object) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)


def learning_curves(
    results: list[dict], path: Path, title: str, analytic: dict | None = None
) -> Path:
    """Return and success rate against env steps: per config the mean over seeds and the
    bootstrap interval of that mean as a band; ``analytic`` (an evaluation summary) as a dashed
    line."""
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.5, 6), constrained_layout=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, entry in enumerate(results):
        color = colors[i % len(colors)]
        label = f"{config_label(entry)} ({len(entry['seeds'])} seeds)"
        for ax, (key, ylabel, scale) in zip(axes, METRICS, strict=True):
            c = entry["curves"][key]
            steps = np.asarray(c["env_steps"])
            ax.plot(steps, scale * np.asarray(c["mean"]), "o-", ms=3, color=color, label=label)
            low, high = scale * np.asarray(c["ci_low"]), scale * np.asarray(c["ci_high"])
            if np.all(np.isfinite(low)):
                ax.fill_between(steps, low, high, color=color, alpha=0.2, lw=0)
            ax.set_ylabel(ylabel)
    if analytic:
        for ax, (key, _, scale) in zip(axes, METRICS, strict=True):
            ax.axhline(scale * analytic[key], ls="--", color="k", label="analytic controller")
    axes[1].set_ylim(-2, 102)
    axes[1].set_xlabel("environment steps")
    axes[0].legend(loc="lower right", fontsize="small")
    axes[0].set_title(f"{title}: mean over seeds, 95% bootstrap band")
    _save(fig, path)
    return path


def final_scores(results: list[dict], path: Path, title: str) -> Path:
    """Final evaluation return and success rate: mean and IQM over seeds with their 95%
    bootstrap intervals, one row per config."""
    panels = [
        (key, stat, ylabel, scale) for key, ylabel, scale in METRICS for stat in ("mean", "iqm")
    ]
    rows = len(results)
    fig, axes = plt.subplots(
        1, len(panels), figsize=(3.2 * len(panels), 1.2 + 0.45 * rows), constrained_layout=True
    )
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    labels = [config_label(e) for e in results]
    for ax, (key, stat, ylabel, scale) in zip(axes, panels, strict=True):
        for y, entry in enumerate(results):
            s = entry[key]
            low, high = (scale * v for v in s[f"{stat}_ci"])
            color = colors[y % len(colors)]
            if np.isfinite(low):
                ax.barh(y, high - low, left=low, height=0.6, color=color, alpha=0.6)
            ax.plot([scale * s[stat]] * 2, [y - 0.3, y + 0.3], color="k", lw=2)
        if key == "success_rate":
            ax.set_xlim(-2, 102)
        ax.set_yticks(range(rows), labels if ax is axes[0] else [""] * rows)
        ax.set_ylim(-0.6, rows - 0.4)
        ax.set_title(f"{'IQM' if stat == 'iqm' else 'mean'} {ylabel}", fontsize="medium")
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(f"{title}: final scores, 95% bootstrap intervals over seeds")
    _save(fig, path)
    return path


def _save(fig: plt.Figure, path: Path) -> None:
    """Atomically, as every file of a run: a reader sees the old figure or the new one."""
    try:
        with atomic_open(path) as f:
            fig.savefig(f, format="png", dpi=110)
    finally:
        plt.close(fig)
