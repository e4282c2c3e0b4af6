"""asphalt_nscd: NonSmooth Contact Dynamics modelling of the complex modulus of asphalt concrete.

Reproduces and extends Quezada & Chazallon, "Complex modulus modeling of asphalt concrete
mixes using the NonSmooth Contact Dynamics method", Computers and Geotechnics 117 (2020) 103255.

Subpackages follow the workflow's chain:

=============  ==============================================================
``lab``        EN 12697-26 2PB reduction (Eqs. 1-5), measured-table ingestion
``rheology``   Burger's and generalized Burger's laws, calibration (Eqs. 27-33, 8-11)
``sample``     numerical sample preparation (Section 3.2.1)
``nscd``       compiled NSCD core: Moreau-Jean, Delassus, nonlinear Gauss-Seidel
``campaign``   numerical 2PB complex modulus test and sensitivity study
``harmonic``   exact steady-state complex modulus of a bonded sample
``diagnosis``  error budget, named causes, extended contact law
``forecast``   a mix's complex modulus from its binder, gradation and volumetrics
``figures``    master-curve figures, rheology plots of tables, the report
=============  ==============================================================

Units: SI inside the code (m, N, Pa, Pa s, kg, s, rad); MPa, degrees, Hz and degC at the
edges (tables, figures, CLI), converted explicitly where read or written.
"""

from importlib import metadata as _metadata

#: The package's stages in the order of their imports: each imports only the ones before it (and
#: ``io``, ``config``). The one list of them: the CLI registers its subcommands in this order, the
#: layer test enforces it and the Snakefile includes ``workflow/rules/<stage>.smk`` in it.
STAGES = ("lab", "rheology", "nscd", "sample", "harmonic", "campaign", "diagnosis", "forecast", "figures")

try:  # one version string: the package metadata (pyproject.toml)
    __version__ = _metadata.version("asphalt-nscd")
except _metadata.PackageNotFoundError:  # pragma: no cover - a source tree that is not installed
    __version__ = "unknown"
