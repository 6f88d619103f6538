"""The learning-curve figure: evaluation return and success rate against env steps."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display needed
import matplotlib.pyplot as plt  # noqa: E402

from rigid_env.files import atomic_open  # noqa: E402


def learning_curve(rows: list[dict], analytic: dict, path: Path, title: str) -> Path:
    """Two panels sharing the x axis (env steps): mean return ± std and success rate of the
    periodic evaluations, each with the analytic controller's level as a dashed line."""
    steps = [r["env_steps"] for r in rows]
    mean = [r["mean_return"] for r in rows]
    std = [r["std_return"] for r in rows]
    success = [100 * r["success_rate"] for r in rows]
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6), constrained_layout=True)
    top.plot(steps, mean, "o-", label="learned (deterministic)")
    low = [m - s for m, s in zip(mean, std, strict=True)]
    high = [m + s for m, s in zip(mean, std, strict=True)]
    top.fill_between(steps, low, high, alpha=0.2)
    top.axhline(analytic["mean_return"], ls="--", color="k", label="analytic controller")
    top.set_ylabel("mean episode return")
    top.legend(loc="lower right")
    bottom.plot(steps, success, "o-", color="tab:green", label="learned (deterministic)")
    bottom.axhline(100 * analytic["success_rate"], ls="--", color="k", label="analytic controller")
    bottom.set_ylabel("success rate (%)")
    bottom.set_ylim(-2, 102)
    bottom.set_xlabel("environment steps")
    bottom.legend(loc="lower right")
    n = rows[-1]["episodes"] if rows else 0
    top.set_title(f"{title}: evaluation on {n} seeded episodes")
    try:
        with atomic_open(path) as f:
            fig.savefig(f, format="png", dpi=110)
    finally:
        plt.close(fig)
    return path
