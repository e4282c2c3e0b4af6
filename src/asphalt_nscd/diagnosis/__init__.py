"""Diagnosis: what the simulation gets wrong, why, and how much an extended law gains.

Modules
-------
synthetic  synthetic measured tables (truth families, replicates, schedules, planted artifacts)
effects    data artifacts: nested fits of a flexible screening model, floors set by the bench
artifacts  the artifact search and master curve of a measured table, written once (JSON +
           corrected table) and read by ``extend-law`` and ``diagnose``
causes     model-form (broad spectrum: held-out errors; static modulus) and simulation
           causes (network factor, time integration: effects against tolerances)
crossval   held-out validation (lofo, loto), nested choice of the settings of the extended
           law (:mod:`asphalt_nscd.rheology.extended`; its file: :mod:`asphalt_nscd.rheology.law_file`)
budget     computing: error budget, baseline/extended MRE, gain; the JSON report of ``diagnose``
render     rendering: gain and cause tables, error-budget figure, the Markdown page
inputs     readers of diagnose's input tables (simulated rows, crossval rows, phase errors, ...)
bench      false-alarm and detection rates per truth family, with 95 % intervals
cli        ``master-curve``, ``extend-law``, ``crossval``, ``diagnose``, ``synth``, ``diagnose-bench``
"""
