"""Forecast: a mix's complex modulus from its binder, gradation and volumetrics.

The paper's future work ("forecasting the viscoelastic properties of an asphalt mixture from
its formulation"), judged on mixes left out. The matched binder-mix table is read by
:mod:`asphalt_nscd.lab.matched` (the lab door); this stage does the science:

Modules
-------
binder      the binder's own data quality (monotonic |G*|, Kramers-Kronig, cold plateau) and a
            master curve per binder fitted on the points that pass
baselines   the formulas pavement engineers use: Witczak 1-37A, Witczak 1-40D, Hirsch, with
            their published coefficients and recalibrated on training mixes
validation  leave-mixes-out validation: folds by mix, errors per temperature with intervals
cli         ``forecast-quality``, ``forecast-crossval``, ``forecast``, ``forecast-page``

Units: SI inside (Pa, Pa s, rad) except where a published equation is written in its own
units (psi, 10^6 P): those functions convert at their edges and say so; MPa and degrees in
tables and pages.
"""
