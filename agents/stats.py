"""Scores over seeds: mean and interquartile mean with bootstrap confidence intervals.

The interquartile mean (IQM: the mean of the middle 50 % of the runs) and percentile-bootstrap
intervals over runs follow Agarwal et al., "Deep Reinforcement Learning at the Edge of the
Statistical Precipice" (NeurIPS 2021), as their library rliable computes them for one task.
rliable itself is not used: its bootstrap dependency (arch) does not import next to the pandas 3
that Ray Tune installs, and for one task its stratified bootstrap is the plain percentile bootstrap
over runs that ``scipy.stats.bootstrap`` gives (Efron & Tibshirani, "An Introduction to the
Bootstrap", 1993, ch. 13).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy import stats

CONFIDENCE = 0.95
RESAMPLES = 2000  # as rliable's default for interval estimates


def iqm(scores: Sequence[float]) -> float:
    """Interquartile mean: ``int(n / 4)`` runs cut from each end, the rest averaged (as
    ``scipy.stats.trim_mean(x, 0.25)``, which rliable uses); equals the mean for ``n < 4``."""
    x = _scores(scores)
    return float(stats.trim_mean(x, 0.25))


def _mean(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis)


def _iqm(x: np.ndarray, axis: int = -1) -> np.ndarray:
    return stats.trim_mean(x, 0.25, axis=axis)


STATISTICS: dict[str, Callable[..., np.ndarray]] = {"mean": _mean, "iqm": _iqm}


def bootstrap_ci(
    scores: Sequence[float] | np.ndarray,
    statistic: str = "mean",
    confidence: float = CONFIDENCE,
    resamples: int = RESAMPLES,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Percentile-bootstrap interval of ``statistic`` (``"mean"`` or ``"iqm"``) over runs.

    ``scores`` is one value per run, or an array (runs, points) for one interval per point (a
    learning curve). With a single run there is no interval: NaN bounds.
    """
    if statistic not in STATISTICS:
        raise ValueError(f"statistic must be one of {sorted(STATISTICS)}, got {statistic!r}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    x = np.asarray(scores, dtype=float)
    if x.ndim == 0 or x.shape[0] == 0:
        raise ValueError("scores: need at least one run")
    if not np.all(np.isfinite(x)):
        raise ValueError("scores: must be finite")
    if x.shape[0] < 2:
        nan = np.full(x.shape[1:], np.nan)
        return nan, nan.copy()
    result = stats.bootstrap(
        (x,),
        STATISTICS[statistic],
        axis=0,
        confidence_level=confidence,
        n_resamples=resamples,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return np.asarray(result.confidence_interval.low), np.asarray(result.confidence_interval.high)


def summarize(scores: Sequence[float], seed: int = 0) -> dict:
    """Mean and IQM of one score over runs, each with its bootstrap interval."""
    x = _scores(scores)
    out: dict = {"n": int(x.size)}
    for name in ("mean", "iqm"):
        low, high = bootstrap_ci(x, name, seed=seed)
        out[name] = float(STATISTICS[name](x))
        out[f"{name}_ci"] = [float(low), float(high)]
    return out


def curve(evaluations: Sequence[Sequence[dict]], key: str, seed: int = 0) -> dict:
    """Mean over runs of ``key`` at each evaluation step that every run reached, with its
    bootstrap band; ``evaluations`` holds one list of evaluation rows (``env_steps``, ``key``)
    per run."""
    if not evaluations:
        raise ValueError("evaluations: need at least one run")
    common = set.intersection(*({r["env_steps"] for r in rows} for rows in evaluations))
    steps = sorted(common)
    values = np.array(
        [[{r["env_steps"]: r[key] for r in rows}[s] for s in steps] for rows in evaluations],
        dtype=float,
    ).reshape(len(evaluations), len(steps))
    low, high = bootstrap_ci(values, "mean", seed=seed) if steps else ([], [])
    return {
        "env_steps": steps,
        "mean": values.mean(axis=0).tolist(),
        "ci_low": np.asarray(low, dtype=float).tolist(),
        "ci_high": np.asarray(high, dtype=float).tolist(),
    }


def aggregate(trials: Sequence[dict], seed: int = 0) -> list[dict]:
    """Group finished trials by config and summarise each config over its seeds.

    A trial is a dict with ``config_key``, ``config``, ``seed`` and ``evaluations`` (the run's
    evaluation rows, the last one being the final model's). Returns one dict per config, in order
    of first appearance: the final ``mean_return`` and ``success_rate`` summarised over seeds
    (:func:`summarize`), the per-seed finals, and learning curves (:func:`curve`).
    """
    groups: dict[str, list[dict]] = {}
    for trial in trials:
        groups.setdefault(trial["config_key"], []).append(trial)
    out = []
    for key, group in groups.items():
        group = sorted(group, key=lambda t: t["seed"])
        finals = [t["evaluations"][-1] for t in group]
        runs = [t["evaluations"] for t in group]
        out.append(
            {
                "config_key": key,
                "config": group[0]["config"],
                "seeds": [t["seed"] for t in group],
                "final": [
                    {
                        "seed": t["seed"],
                        "mean_return": f["mean_return"],
                        "success_rate": f["success_rate"],
                    }
                    for t, f in zip(group, finals, strict=True)
                ],
                "mean_return": summarize([f["mean_return"] for f in finals], seed),
                "success_rate": summarize([f["success_rate"] for f in finals], seed),
                "curves": {k: curve(runs, k, seed) for k in ("mean_return", "success_rate")},
            }
        )
    return out


def _scores(scores: Sequence[float]) -> np.ndarray:
    x = np.asarray(scores, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"scores: need a non-empty list of numbers, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("scores: must be finite")
    return x
