"""Diagnosis: what the simulation gets wrong, why, and how much an extended law gains.

Modules
-------
synthetic  synthetic measured tables (2S2P1D + WLF truth, replicates, planted artifacts)
effects    data artifacts: nested master-curve fits, forward selection with F-tests
causes     model-form (broad spectrum, static modulus) and simulation causes
           (network factor, time integration)
extend     the temperature-aware generalized Burger's law (2S2P1D backbone + Prony chain at
           T_ref, shift law), written per temperature for the NSCD core
crossval   held-out validation (lofo, loto), nested choice of the law's settings
report     error budget, baseline/extended MRE, gain; the JSON report of ``diagnose``
bench      detection and false-alarm rates over synthetic seeds
cli        ``extend-law``, ``crossval``, ``diagnose``, ``synth``, ``diagnose-bench``
"""
