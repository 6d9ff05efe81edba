"""Helpers the tests share: MuJoCo-vs-SAPIEN lockstep stepping, the corpus, MuJoCo as the oracle, the house rules."""
