"""madsim: a pure-Python, TORCS-like driving simulator for reinforcement learning."""

__version__ = "0.1.0"
