"""Robustness: mutated real documents (`mutations`), each loaded and stepped in its own process and judged with
MuJoCo as the oracle (`outcome`), over the corpus (`session`). `python -m conformance robustness`."""
