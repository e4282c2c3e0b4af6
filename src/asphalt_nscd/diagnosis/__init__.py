"""Diagnosis: what the simulation gets wrong, why, and how much an extended law gains.

Modules
-------
synthetic  synthetic measured tables (truth families, replicates, schedules, planted artifacts)
effects    data artifacts: nested fits of a flexible screening model, floors set by the bench
causes     model-form (broad spectrum: held-out errors; static modulus) and simulation
           causes (network factor, time integration: effects against tolerances)
extend     the temperature-aware generalized Burger's law (2S2P1D backbone + Prony chain at
           T_ref, shift law), written per temperature for the NSCD core
crossval   held-out validation (lofo, loto), nested choice of the law's settings
report     error budget, baseline/extended MRE, gain; the JSON report of ``diagnose``
bench      false-alarm and detection rates per truth family, with 95 % intervals
cli        ``extend-law``, ``crossval``, ``diagnose``, ``synth``, ``diagnose-bench``
"""
