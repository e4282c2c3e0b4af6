"""Diagnosis: what the simulation gets wrong, why, and how much an extended law gains.

Modules
-------
synthetic  synthetic measured tables (2S2P1D + WLF truth, replicates, planted artifacts)
effects    data artifacts: nested master-curve fits, forward selection with F-tests
causes     model-form (broad spectrum, static modulus) and simulation causes
           (network factor, time integration)
extend     generalized Burger's law per temperature from the master curve
report     error budget, baseline/extended MRE, gain; the JSON report of ``diagnose``
bench      detection and false-alarm rates over synthetic seeds
cli        ``diagnose``, ``synth``, ``diagnose-bench``
"""
