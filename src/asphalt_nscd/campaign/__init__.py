"""Numerical 2PB complex modulus test, campaign, sensitivity and units studies (Sections 3.2-4).

Modules
-------
twopb   one test: sample + Burger's bonds + driven head plate, record (HDF5), checkpoint/resume,
        reduction by the lab code (EN 12697-26 Eqs. 1-5, :mod:`asphalt_nscd.lab.en12697`)
study   parameter tables per mode, numerical isotherms, Table 4 analogue, sensitivity table,
        the Table 3 units question, phase error of the dt policy
modes   the job modes read from a workflow config: schedule, Table 3 reading, verification jobs,
        the campaign commands' option values from --config
figures Figs. 6-14 analogues
bench   time per step and projected campaign time
cli     subcommands run-2pb, campaign-*
"""
