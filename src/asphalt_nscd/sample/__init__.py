"""Numerical sample preparation (paper Section 3.2.1).

Modules
-------
psd        Table 1 (PSD) -> sphere counts per diameter, comparison with Table 2
settings   the ``sample`` config section: paper defaults, loading, the ``scale`` rule
geometry   lattice placement, trapezoid cut, flip, shrink, density, bonds, descriptors
dynamics   deposition, vibration and bonded stabilisation with the NSCD core
prepare    the whole chain for one seed (:func:`prepare.prepare_sample`) and the summary
store      HDF5 sample file of docs/design.md, ParaView (VTU) files
rig        the 2PB rig: sample + plates + head motion + law -> an NSCD simulation ready to step
figures    Fig. 5-like picture of the stages
cli        ``asphalt-nscd prepare-sample`` and ``asphalt-nscd sample-table``

Read :mod:`.prepare` first: its docstring lists the stages and the choices made where the
paper is silent; :mod:`.settings` explains how ``scale`` and ``psd.cut_mm`` make small samples.
"""
