"""The tiny training budget the agent tests share: 2 envs, an 8-unit network, one epoch of 32
steps, 2 evaluation episodes, no periodic evaluation (as ``--set`` arguments of the CLIs)."""

TINY_SET = [
    "--set",
    "n_steps=32",
    "batch_size=32",
    "n_epochs=1",
    "eval_freq=100000",
    "eval_episodes=2",
    "policy_kwargs={net_arch: [8]}",
]
