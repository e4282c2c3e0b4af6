"""Linear fast path: a step of a bonded network without active contacts is a linear system.

With no contact reaction and no breakage, every bond obeys the affine law P_b = c0_b -
G_b U_b (Eq. 25, local_laws.py; G_b = F_b^T diag(c_g) F_b, constant for a given dt, theta
and bond parameters) with U_b = L_b x its relative velocity. Eliminating the impulses gives,
on the unknown velocities x,

    (M + sum_b L_b^T G_b L_b) x = M x_free + sum_b L_b^T q_b,

q_b = F_b^T (c0_b - diag(c_g) F_b U_b,known) (U_b,known: the part of the bond velocity
from known velocities: fixed spheres, fixed or driven plates). The matrix is symmetric
positive definite and constant while the set of intact bonds does not change.

Unknowns (:mod:`.dofs`): 3-dof blocks, body by body, a body's translation block followed
by its rotation block. With 'barycentre' bond kinematics only translation blocks exist,
L_b = [I, -I]; with 'contact' (state.Bonds) the bond velocity is taken at the contact point
with the lever arms a_i, a_j: L_b = [I, -[a_i]x] on the candidate's (translation, rotation)
and [-I, +[a_j]x] on the antagonist's. M holds the masses and rotational inertias.

Solvers, chosen by ``NSCDParameters.linear_solver`` and run by :class:`LinearBondSolver`:

* ``cg`` (default, :mod:`.cg`): matrix-free conjugate gradient, 3x3 block-Jacobi
  preconditioner, stopped at |r| <= ``linear_tolerance`` |rhs|; initial guess the caller's
  (moreau_jean.py: linear extrapolation in time); ``threads`` > 1 runs it on numba threads.
* ``cg_ssor`` (:mod:`.ssor`): the same conjugate gradient preconditioned by SSOR on the
  body blocks in Eisenstat's form, started from the Galerkin combination of the last
  velocity fields; sequential.
* ``direct`` (:mod:`.direct`): symmetric-mode SuperLU factorisation once per (dt, theta,
  intact-bond set), two triangular solves per step, exact to round-off (the reference).

Validity is checked after the solve by the caller (moreau_jean.py): an iterative solve that
ran to its iteration limit above its tolerance is not the step's solution (the step is redone by
NLGS, warm-started from it, and counted: ``Simulation.linear_unconverged``); every contact candidate
must satisfy U_n + max(g, 0)/h >= 0 with zero reaction, and no bond may exceed R_crit;
otherwise the step is redone by NLGS, unless at most ``NSCDParameters.fast_path_contacts``
contacts close, which are then solved on their Delassus operator condensed over the bonds
(condensed.py, with the columns of A^-1 of :meth:`LinearBondSolver.response`; a column whose
solve does not converge sends the step to NLGS too). Measured
costs and the variants tried: docs/choices.md.
"""

from .cg import CGOperator
from .direct import PermutedLU, splu_symmetric
from .dofs import DofMap, bond_impulses, dof_numbering, skew
from .solver import LINEAR_SOLVERS, LinearBondSolver, LinearSolveError
from .ssor import SSORStructure, ssor_structure

# kernels that the unit tests call as linear.<name> (tests/unit/test_nscd_linear.py,
# test_nscd_threads.py)
from .cg import _bonds, _matvec, _partition  # noqa: E402,F401
from .ssor import _SSOR_KEYS, _lower_solve, _upper_solve  # noqa: E402,F401

__all__ = [
    "LINEAR_SOLVERS",
    "LinearBondSolver",
    "LinearSolveError",
    "PermutedLU",
    "splu_symmetric",
    "bond_impulses",
    "dof_numbering",
    "skew",
    "ssor_structure",
    "CGOperator",
    "DofMap",
    "SSORStructure",
]
