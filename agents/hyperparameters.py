"""Hyperparameters checked before training: the values stable-baselines3 accepts but cannot
train with (a discount above 1, no epochs, a layer of negative width, a learning rate of zero
or infinity), refused with the parameter named.

:func:`check` takes the values as a config file or ``--set`` gives them (``"lin_1e-3"``, a
``policy_kwargs`` expression) or as :func:`agents.config.resolve` makes them; keys without a
rule here are left to SB3's own constructor. :func:`check_combination` checks what depends on
the number of envs, and :func:`memory_bytes` estimates what training needs.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any

from rigid_env.cli import UsageError

Rule = Callable[[Any], bool]


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def integer(minimum: int) -> tuple[Rule, str]:
    return (lambda v: _is_int(v) and v >= minimum), f"an integer >= {minimum}"


def number(
    low: float, high: float = math.inf, low_open: bool = False, high_open: bool = False
) -> tuple[Rule, str]:
    def rule(v: Any) -> bool:
        if not _is_number(v):
            return False
        x = float(v)
        above = x > low if low_open else x >= low
        below = x < high if high_open else x <= high
        return above and below

    left, right = "(" if low_open else "[", ")" if high_open or high == math.inf else "]"
    if high == math.inf:
        text = f"a finite number {'>' if low_open else '>='} {low:g}"
    else:
        text = f"a number in {left}{low:g}, {high:g}{right}"
    return rule, text


def _positive_or_linear(v: Any) -> bool:
    """A positive finite number, ``"lin_<positive>"`` or a resolved linear schedule."""
    from .config import linear_schedule

    if isinstance(v, linear_schedule):
        v = v.initial
    elif isinstance(v, str) and v.startswith("lin_"):
        try:
            v = float(v[4:])
        except ValueError:
            return False
    return _is_number(v) and float(v) > 0


RATE = (_positive_or_linear, 'a finite number > 0 or "lin_<number > 0>" (a linear schedule)')
BOOL = ((lambda v: isinstance(v, bool)), "true or false")
OPTIONAL_POSITIVE = (
    (lambda v: v is None or number(0, low_open=True)[0](v)),
    "null or a number > 0",
)


def _sac_ent_coef(v: Any) -> bool:
    if isinstance(v, str) and v.startswith("auto"):
        rest = v[len("auto") :]
        if not rest:
            return True
        if not rest.startswith("_"):
            return False
        try:
            return _is_number(float(rest[1:])) and float(rest[1:]) > 0
        except ValueError:
            return False
    return _is_number(v) and float(v) > 0


def _train_freq(v: Any) -> bool:
    if _is_int(v):
        return v >= 1
    if isinstance(v, (list, tuple)) and len(v) == 2:
        return _is_int(v[0]) and v[0] >= 1 and v[1] in ("step", "episode")
    return False


COMMON: dict[str, tuple[Rule, str]] = {
    "policy": ((lambda v: v == "MlpPolicy"), '"MlpPolicy" (the envs observe flat vectors)'),
    "learning_rate": RATE,
    "gamma": number(0, 1, low_open=True),
    "batch_size": integer(1),
    "use_sde": BOOL,
    "sde_sample_freq": integer(-1),
    "stats_window_size": integer(1),
}
RULES: dict[str, dict[str, tuple[Rule, str]]] = {
    "ppo": {
        **COMMON,
        "n_steps": integer(1),
        "n_epochs": integer(1),
        "gae_lambda": number(0, 1),
        "clip_range": RATE,
        "clip_range_vf": ((lambda v: v is None or _positive_or_linear(v)), f"null or {RATE[1]}"),
        "normalize_advantage": BOOL,
        "ent_coef": number(0),
        "vf_coef": number(0),
        "max_grad_norm": number(0, low_open=True),
        "target_kl": OPTIONAL_POSITIVE,
    },
    "sac": {
        **COMMON,
        "buffer_size": integer(1),
        "learning_starts": integer(0),
        "tau": number(0, 1, low_open=True),
        "train_freq": (_train_freq, 'an integer >= 1 or [integer >= 1, "step" or "episode"]'),
        "gradient_steps": (
            (lambda v: _is_int(v) and (v >= 1 or v == -1)),
            "an integer >= 1, or -1 (as many as env steps)",
        ),
        "ent_coef": (_sac_ent_coef, 'a finite number > 0, "auto" or "auto_<number > 0>"'),
        "target_update_interval": integer(1),
        "target_entropy": ((lambda v: v == "auto" or _is_number(v)), '"auto" or a finite number'),
        "use_sde_at_warmup": BOOL,
        "optimize_memory_usage": BOOL,
        "n_steps": integer(1),
    },
}
NET_KEYS = {"ppo": ("pi", "vf"), "sac": ("pi", "qf")}


def _widths(value: Any) -> bool:
    return isinstance(value, (list, tuple)) and all(_is_int(w) and w >= 1 for w in value)


def _activation(value: Any) -> bool:
    import torch.nn

    if isinstance(value, str):
        value = getattr(torch.nn, value, None)
    return isinstance(value, type) and issubclass(value, torch.nn.Module)


def policy_rules(algo: str) -> dict[str, tuple[Rule, str]]:
    pi, other = NET_KEYS[algo]

    def net_arch(v: Any) -> bool:
        if isinstance(v, Mapping):
            return bool(v) and set(v) <= {pi, other} and all(_widths(w) for w in v.values())
        return _widths(v)

    rules = {
        "net_arch": (
            net_arch,
            f"a list of layer widths (integers >= 1), or a dict of such lists for {pi!r} "
            f"and {other!r}",
        ),
        "activation_fn": (_activation, "a torch.nn activation, e.g. nn.Tanh or nn.ReLU"),
        "log_std_init": number(-math.inf),
        "ortho_init": BOOL,
        "squash_output": BOOL,
        "share_features_extractor": BOOL,
        "full_std": BOOL,
        "use_expln": BOOL,
    }
    if algo == "sac":
        rules["n_critics"] = integer(1)
    return rules


def check(algo: str, params: Mapping[str, Any], source: str) -> None:
    """:class:`UsageError` (a ``ValueError``) naming ``source`` and the first parameter of
    ``params`` whose value cannot train."""
    from .config import policy_kwargs

    rules = RULES[algo]
    for key, value in params.items():
        if key == "policy_kwargs":
            try:
                kwargs = policy_kwargs(value)
            except Exception as error:  # the Zoo's expression, evaluated over dict and nn
                raise UsageError(
                    f"{source}: policy_kwargs {value!r} is not a dict or a dict(...) expression "
                    f"({type(error).__name__}: {error})"
                ) from None
            for name, entry in kwargs.items():
                if name in (policy := policy_rules(algo)):
                    rule, expected = policy[name]
                    if not rule(entry):
                        raise UsageError(
                            f"{source}: policy_kwargs {name} must be {expected}, got {entry!r}"
                        )
        elif key in rules:
            rule, expected = rules[key]
            if not rule(value):
                raise UsageError(f"{source}: {key} must be {expected}, got {value!r}")


def check_combination(algo: str, kwargs: Mapping[str, Any], n_envs: int, source: str) -> None:
    """What depends on other settings: PPO normalises advantages over a minibatch (unless
    ``normalize_advantage`` is false), so a minibatch and a rollout need more than one step."""
    if algo == "ppo" and kwargs.get("normalize_advantage", True):
        n_steps, batch_size = kwargs.get("n_steps", 2048), kwargs.get("batch_size", 64)
        if _is_int(batch_size) and batch_size < 2:
            raise UsageError(
                f"{source}: batch_size must be >= 2 (advantages are normalised over a "
                f"minibatch; set normalize_advantage=false for 1), got {batch_size}"
            )
        if _is_int(n_steps) and n_steps * n_envs <= 1:
            raise UsageError(
                f"{source}: n_steps x n_envs must be > 1 (advantages are normalised over a "
                f"rollout), got n_steps {n_steps} with n_envs {n_envs}"
            )


def _layers(widths: list[int], inputs: int, outputs: int) -> float:
    sizes = [inputs, *widths, outputs]
    return float(sum((a + 1) * b for a, b in zip(sizes, sizes[1:], strict=False)))


def memory_bytes(
    algo: str, kwargs: Mapping[str, Any], n_envs: int, timesteps: int, spaces: tuple[int, int]
) -> dict[str, float]:
    """Bytes training needs at least, by part: SB3's buffer (float32; a replay buffer as far as
    ``timesteps`` fill it) and the networks (weights, gradients and Adam's two moments, float32);
    ``spaces`` = (observation, action) sizes."""
    from .config import policy_kwargs

    obs, act = spaces
    arch = policy_kwargs(kwargs.get("policy_kwargs")).get("net_arch", [64, 64])
    pi, other = NET_KEYS[algo]
    if isinstance(arch, Mapping):
        actor, critic = list(arch.get(pi, [])), list(arch.get(other, []))
    else:
        actor = critic = list(arch)
    if algo == "ppo":
        buffer = float(kwargs.get("n_steps", 2048)) * n_envs * (obs + act + 6) * 4
        params = _layers(actor, obs, act) + _layers(critic, obs, 1)
    else:
        copies = 1 if kwargs.get("optimize_memory_usage") else 2
        filled = min(float(kwargs.get("buffer_size", 1_000_000)), float(timesteps + n_envs))
        buffer = filled * (copies * obs + act + 3) * 4
        critics = policy_kwargs(kwargs.get("policy_kwargs")).get("n_critics", 2)
        params = _layers(actor, obs, 2 * act) + 2 * critics * _layers(critic, obs + act, 1)
    return {"buffer": buffer, "networks": 16.0 * params}
