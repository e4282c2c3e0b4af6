"""Periodic steady state of a bonded sample under a harmonic head displacement.

In the small-strain complex modulus test no bond breaks and no contact opens or closes, so
the sample is a linear viscoelastic network of rigid spheres. Under the top-plate
displacement Re(A e^{i w t}) every unknown is a phasor and :class:`HarmonicSystem` solves one
sparse system per (T, f), bottom plate fixed:

    (K(w) - w^2 M)_ff u_f = -K(w)_fp u_p,           u_p = (A, 0, 0)   (top plate)

Bond b has K_b(w) = k_n n n^T + k_t (I - n n^T), k_n = a_b E*(w), a_b = pi r_min^2 / l0,
k_t = k_n / (2 (1 + nu)) (Eqs. 30-33, 8-11; E*(w) of any law with ``complex_modulus(omega)``,
docs/design.md, Bond law): the exact frequency response of the time-domain bond law
(Eqs. 15-24) for intact bonds and small strain. The head force is the actuator's
(``inertia="full"``) or, without masses, what a load cell would read with EN 12697-26's
lumped mass mu = 0.135 M + m (``inertia="none"``). With one law, K(w) - w^2 M = E*(w) (G - s M),
s = w^2 / E*(w), G real: without inertia the network factor is a real constant.

Choices (docs/choices.md, Bond kinematics; Harmonic solver speed):
* ``bond_kinematics``: ``contact`` (default, 6 DOF, bond at its contact point) or ``barycentre``;
* ``head_rotation``: ``free`` (default, the cantilever of Eq. 3) or ``clamped``;
* zero modes regularised by a rotational spring, eps = ``ROTATIONAL_REGULARISATION`` (1e-10);
* SuperLU in METIS nested-dissection order (:mod:`.ordering`), real factorisations only;
* with inertia, GMRES preconditioned by the real factor of G - Re(s) M, reused over a band
  of Re(s), with one BLAS thread; ``direct`` (one complex LU) is the tests' reference.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from ..nscd.linear import PermutedLU, splu_symmetric
from ..nscd.state import BOND_KINEMATICS, HEAD_AMPLITUDE_M, HEAD_ROTATIONS
from ..rheology.laws import POISSON_RATIO, tangential_ratio
from .network import BondNetwork
from .ordering import ORDERINGS, nested_dissection

INERTIA_MODES = ("none", "full")
#: Relative stiffness eps of the regularising rotational bond spring (docs/choices.md, Bond kinematics).
ROTATIONAL_REGULARISATION = 1e-10
SOLVERS = ("reuse", "direct")
#: A cached real factor of G - sigma_c M is reused for the shift sigma = Re(s) when
#: sigma_c / SHIFT_REUSE_BELOW <= sigma <= sigma_c * SHIFT_REUSE_ABOVE (iteration counts in
#: docs/choices.md, Harmonic solver speed: a factorisation costs about as much as 70 GMRES iterations).
SHIFT_REUSE_BELOW = 100.0
SHIFT_REUSE_ABOVE = 20.0
#: GMRES iterations (no restart) before a reused shifted factor is replaced by a new one.
GMRES_MAX_ITERATIONS = 80
#: Memory for the cached shifted factors besides G, bytes: factors are kept, least recently
#: used dropped first, while their estimated size stays within it; one is always kept. A sweep
#: or a cross-validation returns to the shifts of earlier temperatures and folds: on a
#: 9,000-sphere sample (about 0.3 GB per factor) one factor made 28 factorisations for a
#: 105-point sweep, six made 6, 32 % less CPU (docs/choices.md, Harmonic solver speed).
SHIFTED_FACTOR_BUDGET_BYTES = 1.5e9
#: Estimated bytes per stored entry of a SuperLU factor (an 8-byte value, a 4-byte row index).
FACTOR_BYTES_PER_ENTRY = 12
#: EN 12697-26 lumped-mass factor of the specimen in mu = 0.135 M + m (Eq. 1).
SPECIMEN_MASS_FACTOR = 0.135


@dataclass
class HarmonicSolution:
    """Steady state at one angular frequency.

    Attributes
    ----------
    frequency_Hz : float
    force : (3,) complex, N
        Force F at the head (x component is the test force; content: module docstring).
    reaction : (3,) complex, N
        R = K_pf u_f + K_pp u_p, minus the sum of the bond forces on the top plate.
    displacement : (N, 3) complex, m
        Sphere displacement phasors (zero for the removed load-free clusters).
    amplitude_m : float
        Imposed head displacement amplitude A.
    mu_kg : float
        Mass factor of Eq. 1, 0.135 M + m (kg).
    sample_mass_kg, plate_mass_kg : float
        M (spheres) and m (top plate) of the sample file, kg.
    inertia : str
        "none" or "full" (see the module docstring).
    n_free_dof, n_load_free : int
        Unknowns solved for; spheres in load-free clusters.
    solve_time_s : float
        Wall time of assembly + solve.
    residual : float
        Relative residual |A u - b| / |b| of the linear system.
    solver : str
        "reuse" or "direct" (see :meth:`HarmonicSystem.solve_law`).
    rotation : (N, 3) complex, rad
        Sphere rotation phasors (zero with the barycentre kinematics).
    head_rotation : (3,) complex, rad
        Head rotation phasor (zero when clamped).
    """

    frequency_Hz: float
    force: np.ndarray
    reaction: np.ndarray
    displacement: np.ndarray
    amplitude_m: float
    mu_kg: float
    sample_mass_kg: float
    plate_mass_kg: float
    inertia: str
    n_free_dof: int
    n_load_free: int
    solve_time_s: float
    residual: float
    solver: str = "direct"
    rotation: np.ndarray | None = None
    head_rotation: np.ndarray | None = None

    @property
    def psi_deg(self) -> float:
        """Phase lead of the force on the displacement, degrees."""
        return float(np.degrees(np.angle(self.force[0] / self.amplitude_m)))

    @property
    def F0_N(self) -> float:
        return float(abs(self.force[0]))


#: relative eigenvalue below which a cluster's own stiffness block has a zero mode
#: (:meth:`HarmonicSystem.mechanism_modes`)
MECHANISM_TOLERANCE = 1e-9


class HarmonicSystem:
    """The bonded network prepared for repeated harmonic solves (pattern built once).

    Parameters
    ----------
    network : BondNetwork
    nu : float
        Poisson's ratio of the tangential ratio 1/(2(1+nu)) (Eqs. 8-11).
    bond_kinematics : {"contact", "barycentre"}
        Where the bond acts; 6 or 3 DOF per sphere (module docstring).
    head_rotation : {"free", "clamped"}
        Whether the head rotates (3 more unknowns) or only translates (module docstring).
    regularisation : float
        eps of the regularising rotational bond spring (``contact`` only; module docstring).
    reference : dict, optional
        The :meth:`reference_state` of a system of the same network and options, computed
        before (e.g. once per sample, :func:`asphalt_nscd.campaign.twopb.write_rig_state`):
        its reference stiffness G and fill-reducing ordering are taken instead of assembled,
        the same to the last bit. The per-bond pattern is then built only if an assembly of
        other stiffnesses needs it (:meth:`blocks`).

    Raises
    ------
    ValueError
        on an unknown option, negative ``regularisation``, ``contact`` without radii, or a
        ``reference`` whose shapes do not fit the network.
    """

    def __init__(
        self,
        network: BondNetwork,
        nu: float = POISSON_RATIO,
        bond_kinematics: str = "contact",
        head_rotation: str = "free",
        regularisation: float = ROTATIONAL_REGULARISATION,
        ordering: str = "metis",
        reference: dict | None = None,
    ):
        if bond_kinematics not in BOND_KINEMATICS:
            raise ValueError(f"bond_kinematics must be one of {BOND_KINEMATICS}, got {bond_kinematics!r}")
        if head_rotation not in HEAD_ROTATIONS:
            raise ValueError(f"head_rotation must be one of {HEAD_ROTATIONS}, got {head_rotation!r}")
        if ordering not in ORDERINGS:
            raise ValueError(f"ordering must be one of {ORDERINGS}, got {ordering!r}")
        if bond_kinematics == "contact" and network.contact_point is None:
            raise ValueError("bond_kinematics='contact' needs the sphere radii (contact points)")
        if not regularisation >= 0:
            raise ValueError(f"regularisation must be >= 0, got {regularisation}")
        self.network = network
        self.t_ratio = tangential_ratio(nu)
        self.bond_kinematics = bond_kinematics
        self.head_rotation = head_rotation
        self.regularisation = float(regularisation)
        self.ordering = ordering
        #: One record per factorisation: kind, shift, times, stored entries (:meth:`factorise`).
        self.factor_log: list[dict] = []
        self._shifted: OrderedDict = OrderedDict()
        contact = bond_kinematics == "contact"
        n_sph = network.n_spheres
        i, j = network.i, network.j
        # Load-free clusters: connected components of the sphere graph touching no plate.
        sph = j >= 0
        graph = sp.coo_matrix((np.ones(sph.sum()), (i[sph], j[sph])), shape=(n_sph, n_sph))
        _, label = connected_components(graph, directed=False)
        anchored = np.zeros(label.max() + 1 if n_sph else 0, bool)
        anchored[label[i[~sph]]] = True
        self.active = anchored[label]
        self.n_load_free = int(n_sph - self.active.sum())
        n_act = int(self.active.sum())
        self.dof_per_sphere = 6 if contact else 3
        d = self.dof_per_sphere
        n_head_rot = 3 if head_rotation == "free" else 0
        self.n_free = d * n_act + n_head_rot
        # Body slots: active spheres 0..n_act-1, top plate n_act, bottom plate n_act + 1.
        # Global DOF of the 6 coordinates (u, theta) of every slot; -1 = fixed / not a DOF.
        # The top plate's translation is prescribed (DOFs n_free..n_free+2, the "p" block).
        act = np.flatnonzero(self.active)
        slot = -np.ones(n_sph + 2, np.int64)
        slot[act] = np.arange(n_act)
        slot[n_sph + 1] = n_act
        slot[n_sph] = n_act + 1
        n_slot = n_act + 2
        gdof = -np.ones((n_slot, 6), np.int64)
        gdof[:n_act, :d] = d * np.arange(n_act)[:, None] + np.arange(d)
        gdof[n_act, :3] = self.n_free + np.arange(3)
        if n_head_rot:
            gdof[n_act, 3:] = d * n_act + np.arange(3)
        self.keep = self.active[i]  # bonds of load-free clusters carry nothing
        a_body = i[self.keep]
        c_body = np.where(j >= 0, j, n_sph - 1 - j)[self.keep]  # -1 -> n_sph, -2 -> n_sph + 1
        sa, sc = slot[a_body], slot[c_body]
        self._slots = (slot, gdof, n_slot, a_body, c_body)
        # Body graph of the free unknowns (spheres, and the head when it rotates) for the
        # nested-dissection ordering: node k holds unknowns node_start[k]:node_start[k+1].
        n_node = n_act + (1 if n_head_rot else 0)
        edge = (sa < n_node) & (sc < n_node)
        self._graph = (n_node, sa[edge], sc[edge], np.r_[d * np.arange(n_act + 1), [self.n_free] if n_head_rot else []])
        mass = np.zeros((n_act, d))
        mass[:, :3] = network.mass[act, None]
        if contact:
            assert network.rotational_inertia is not None  # given with the contact points
            mass[:, 3:] = network.rotational_inertia[act, None]
        head = np.asarray(network.plate_inertia if network.plate_inertia is not None else np.zeros(3), float)[
            :n_head_rot
        ]
        self.mass_free = np.concatenate([mass.ravel(), head])
        if reference is not None:
            self._take_reference(reference)

    def reference_state(self) -> dict:
        """What a job on this network needs and no law changes, to give another system of the
        same network and options (``reference``): ``{"G": {block: CSC matrix}, "permutation":
        (n_free,) int64 or None, "network_sha256": the network's digest, "options":
        :meth:`options`}``, the blocks of :meth:`_reference_blocks` (N/m per unit
        a_b, blocks ff (n_free, n_free), fp (n_free, 3), pf (3, n_free), pp (3, 3)) and the
        ordering of :meth:`permutation`."""
        return {
            "G": dict(self._reference_blocks()),
            "permutation": self.permutation(),
            "network_sha256": self.network.digest(),
            "options": self.options(),
        }

    def options(self) -> str:
        """The options that shape G and its ordering, as one string (checked by ``reference``)."""
        return (
            f"nu-ratio {self.t_ratio!r}, {self.bond_kinematics}, head {self.head_rotation}, "
            f"regularisation {self.regularisation!r}, ordering {self.ordering}"
        )

    def _take_reference(self, reference: dict) -> None:
        """Adopt a :meth:`reference_state` after checking its network digest and shapes."""
        if reference.get("network_sha256") != self.network.digest():
            raise ValueError("reference: computed on another network (its network_sha256 differs)")
        if reference.get("options") != self.options():
            raise ValueError(f"reference: computed with options {reference.get('options')!r}, not {self.options()!r}")
        n = self.n_free
        want = {"ff": (n, n), "fp": (n, 3), "pf": (3, n), "pp": (3, 3)}
        g = reference.get("G", {})
        perm = reference.get("permutation")
        for name, shape in want.items():
            if name not in g or tuple(g[name].shape) != shape:
                got = None if name not in g else tuple(g[name].shape)
                raise ValueError(f"reference: block {name} of G has shape {got}, expected {shape} for this network")
        if perm is not None and (perm.shape != (n,) or not np.array_equal(np.sort(perm), np.arange(n))):
            raise ValueError(f"reference: the permutation is not one of the {n} free unknowns")
        self._ref_blocks = {name: sp.csc_matrix(g[name]) for name in want}
        if perm is not None:
            self._perm = np.asarray(perm, np.int64)

    def _pattern(self) -> None:
        """The per-bond 6x6 blocks of the unit normal and tangential stiffnesses and their
        assembly pattern (:meth:`blocks`): built on the first assembly, which a system given
        its reference stiffness G (``reference``) may never need."""
        if hasattr(self, "_blocks"):
            return
        network = self.network
        contact = self.bond_kinematics == "contact"
        slot, gdof, n_slot, a_body, c_body = self._slots
        n = network.normal[self.keep]
        # Point where the bond acts: contact point, or the barycentre of sphere i.
        if contact:
            assert network.contact_point is not None  # checked above
            point = network.contact_point[self.keep]
        else:
            point = network.position[a_body]
        centre = np.vstack(
            [network.position, network.plate_point if network.plate_point is not None else np.zeros((2, 3))]
        )
        # L (B, 6, 6) per side: (relative displacement at the point, relative rotation)
        # = L_c q_c - L_a q_a with L = [[I, -skew(point - centre)], [0, I]].
        arm_a = point - centre[a_body]
        lever_a, lever_c = _lever(arm_a), _lever(point - centre[c_body])
        nb = len(a_body)
        pn = np.einsum("bk,bl->bkl", n, n)
        unit_n = np.zeros((nb, 6, 6))
        unit_t = np.zeros((nb, 6, 6))
        unit_n[:, :3, :3] = pn
        unit_t[:, :3, :3] = np.eye(3) - pn
        # Regularising rotational spring eps k_n l^2 (module docstring): l = |c - x_a| with
        # the contact kinematics; with the barycentre one only the head rotates, l = |c - p|.
        arm = arm_a if contact else point - centre[c_body]
        arm2 = np.einsum("bk,bk->b", arm, arm)
        unit_n[:, 3:, 3:] = (self.regularisation * arm2)[:, None, None] * np.eye(3)
        # 6x6 blocks of bond b on the slot pairs (a,a), (c,c), (a,c), (c,a):
        # L_a^T U L_a, L_c^T U L_c, -L_a^T U L_c, -L_c^T U L_a (U = unit_n or unit_t).
        sa, sc = slot[a_body], slot[c_body]
        lat, lct = lever_a.transpose(0, 2, 1), lever_c.transpose(0, 2, 1)
        blocks_n, blocks_t = [], []
        for left, right, sign in ((lat, lever_a, 1.0), (lct, lever_c, 1.0), (lat, lever_c, -1.0), (lct, lever_a, -1.0)):
            blocks_n.append(sign * (left @ unit_n @ right))
            blocks_t.append(sign * (left @ unit_t @ right))
        self._unit_n = np.concatenate(blocks_n)  # (4B, 6, 6)
        self._unit_t = np.concatenate(blocks_t)
        self._src = np.tile(np.arange(nb), 4)
        pair_r = np.concatenate([sa, sc, sa, sc])
        pair_c = np.concatenate([sa, sc, sc, sa])
        # Sum the blocks of each slot pair: sort once, np.add.reduceat per assembly.
        key = pair_r * n_slot + pair_c
        self._order = np.argsort(key, kind="stable")
        sorted_key = key[self._order]
        first = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]]) if nb else np.zeros(0, np.int64)
        self._starts = first
        ukey = sorted_key[first]
        rows = gdof[ukey // n_slot][:, :, None]  # (U, 6, 1)
        cols = gdof[ukey % n_slot][:, None, :]  # (U, 1, 6)
        nonzero = self._reduce(np.abs(self._unit_n) + np.abs(self._unit_t)) != 0
        valid = (rows >= 0) & (cols >= 0) & nonzero
        rows = np.broadcast_to(rows, valid.shape)[valid]
        cols = np.broadcast_to(cols, valid.shape)[valid]
        self._valid = np.flatnonzero(valid.ravel())
        # Split the entries into the blocks ff, fp (rows free) and pf, pp (rows top).
        self._blocks = {}
        for name, rsel, csel in (
            ("ff", rows < self.n_free, cols < self.n_free),
            ("fp", rows < self.n_free, cols >= self.n_free),
            ("pf", rows >= self.n_free, cols < self.n_free),
            ("pp", rows >= self.n_free, cols >= self.n_free),
        ):
            sel = np.flatnonzero(rsel & csel)
            r0 = 0 if name[0] == "f" else self.n_free
            c0 = 0 if name[1] == "f" else self.n_free
            shape = (self.n_free if name[0] == "f" else 3, self.n_free if name[1] == "f" else 3)
            self._blocks[name] = (sel, rows[sel] - r0, cols[sel] - c0, shape)

    def mechanism_modes(self, max_bonds: int = 3):
        """Zero modes of the weakly held spheres (mechanisms): the spheres with at most
        ``max_bonds`` bonds, grouped into the connected clusters they form among themselves,
        and for each cluster the null vectors of its own block of the unregularised G (its
        neighbours held), relative eigenvalue below :data:`MECHANISM_TOLERANCE`. Such a vector
        strains no bond, so it is a zero mode of the whole network: a sphere held by one bond
        rolls about its contact point, one held by two spins about the line through both.
        Only the ``contact`` kinematics has them (a barycentre bond holds a sphere in full).

        Yields, per cluster with zero modes, (free DOF indices (k,), orthonormal null vectors
        (k, m), stiffness scale of the cluster's block, sphere indices of the cluster).
        """
        from scipy.sparse.csgraph import connected_components

        net = self.network
        n = net.n_spheres
        d = self.dof_per_sphere
        count = np.bincount(net.i, minlength=n) + np.bincount(net.j[net.j >= 0], minlength=n)
        slot = -np.ones(n, np.int64)
        slot[self.active] = np.arange(int(self.active.sum()))
        weak = (count <= max_bonds) & (slot >= 0)
        if not weak.any():
            return
        both = net.j >= 0
        both[both] = weak[net.i[both]] & weak[net.j[both]]
        graph = sp.coo_matrix((np.ones(both.sum()), (net.i[both], net.j[both])), shape=(n, n))
        _, label = connected_components(graph, directed=False)
        if self.regularisation:
            raise ValueError(
                "mechanism_modes: the zero modes of the bonds alone need a system built with regularisation=0"
            )
        g = self._reference_blocks()["ff"].tocsr()
        for lab in np.unique(label[weak]):
            spheres = np.flatnonzero(weak & (label == lab))
            dofs = (d * slot[spheres][:, None] + np.arange(d)).ravel()
            w, vec = np.linalg.eigh(g[dofs][:, dofs].toarray())
            scale = max(float(w.max()), 1e-300)
            null = w < MECHANISM_TOLERANCE * scale
            if null.any():
                yield dofs, vec[:, null], scale, spheres

    def _reduce(self, entry) -> np.ndarray:
        """Sum of per-(bond, slot pair) 6x6 blocks (4B, 6, 6) per slot pair -> (U, 6, 6)."""
        if len(self._starts) == 0:
            return np.zeros((0, 6, 6), entry.dtype)
        return np.add.reduceat(entry[self._order], self._starts, axis=0)

    def blocks(self, kn, kt) -> dict:
        """Sparse blocks ff, fp, pf, pp of K(w) for per-bond stiffnesses kn, kt (B,) N/m.

        Real stiffnesses give real (float64) blocks, complex ones complex blocks (CSC).
        """
        self._pattern()
        kn = np.asarray(kn)[self.keep][self._src][:, None, None]
        kt = np.asarray(kt)[self.keep][self._src][:, None, None]
        data = self._reduce(kn * self._unit_n + kt * self._unit_t).ravel()[self._valid]
        out = {}
        for name, (sel, r, c, shape) in self._blocks.items():
            out[name] = sp.csc_matrix((data[sel], (r, c)), shape=shape)
        return out

    def permutation(self) -> np.ndarray | None:
        """Fill-reducing ordering of the free unknowns (None: SuperLU's MMD(A^T + A)).

        ``ordering="metis"``: METIS nested dissection of the body graph expanded to the
        d-DOF blocks (:mod:`.ordering`), computed once per system.
        """
        if self.ordering == "mmd" or self.n_free == 0:
            return None
        if not hasattr(self, "_perm"):
            from .ordering import expand_blocks

            n_node, ei, ej, start = self._graph
            self._perm = expand_blocks(nested_dissection(n_node, ei, ej), start)
        return self._perm

    def factorise(self, a, kind: str = "", shift: float = 0.0):
        """SuperLU factor (symmetric mode) of a free-free matrix in the system's ordering.

        Records kind, shift, ordering and factor times and SuperLU's stored entries
        (``lu.nnz``; L.nnz + U.nnz would copy the factors) in :attr:`factor_log`.
        """
        t0 = time.perf_counter()
        perm = self.permutation()
        t1 = time.perf_counter()
        lu = splu_symmetric(a, perm)
        if perm is None:  # same solve interface (complex right-hand sides of a real factor)
            lu = PermutedLU(lu, np.arange(a.shape[0]), a.dtype)
        self.factor_log.append(
            {
                "kind": kind,
                "shift": float(shift),
                "ordering": self.ordering,
                "ordering_s": t1 - t0,
                "factor_s": time.perf_counter() - t1,
                "stored_entries": int(lu.nnz),
                "n": int(a.shape[0]),
            }
        )
        return lu

    def _reference(self) -> dict:
        """Real reference stiffness G = K(k_n = a_b, k_t = a_b / (2(1+nu))) and its LU factor.

        When every bond follows the same law, K(w) = E*(w) G; G is factorised once per sample.
        """
        if not hasattr(self, "_ref"):
            blk = dict(self._reference_blocks())
            blk["lu"] = self.factorise(blk["ff"], "G") if self.n_free else None
            self._ref = blk
        return self._ref

    def _reference_blocks(self) -> dict:
        """G's blocks without factorising it (the inertia path needs G - sigma M only)."""
        if not hasattr(self, "_ref_blocks"):
            kn = self.network.scale.astype(float)
            self._ref_blocks = self.blocks(kn, kn * self.t_ratio)
        return self._ref_blocks

    def shifted_factor(self, sigma: float, reuse: bool = True):
        """Real factor of G - sigma M, reused from the cache when a cached shift is near.

        Parameters
        ----------
        sigma : float, 1/s^2 per Pa (the real part of s = w^2 / E*).
        reuse : bool
            Reuse a cached factor of shift sigma_c if sigma_c / :data:`SHIFT_REUSE_BELOW` <=
            sigma <= sigma_c * :data:`SHIFT_REUSE_ABOVE` (the nearest in log scale). The
            cache keeps factors within :data:`SHIFTED_FACTOR_BUDGET_BYTES` (least recently
            used dropped first, at least one kept).

        Returns
        -------
        (factor, sigma_used, reused)
        """
        best = None
        for sc in self._shifted if reuse else ():
            if sc > 0 and sigma > 0 and sc / SHIFT_REUSE_BELOW <= sigma <= sc * SHIFT_REUSE_ABOVE:
                dist = abs(np.log(sigma / sc))
                if best is None or dist < best[0]:
                    best = (dist, sc)
        if best is not None:
            self._shifted.move_to_end(best[1])
            return self._shifted[best[1]], best[1], True
        # free memory before factorising; the new factor has the cached ones' pattern, about their size
        while self._shifted:
            sizes = [FACTOR_BYTES_PER_ENTRY * f.nnz for f in self._shifted.values()]
            if sum(sizes) + max(sizes) <= SHIFTED_FACTOR_BUDGET_BYTES:
                break
            self._shifted.popitem(last=False)
        g = self._reference_blocks()["ff"]
        a = (g - sigma * sp.diags(self.mass_free, format="csc")).tocsc()
        try:
            lu = self.factorise(a, "G - sigma M", sigma)
        except RuntimeError:  # exactly singular at this shift: move it slightly
            sigma = sigma * (1.0 + 1e-6)
            a = (g - sigma * sp.diags(self.mass_free, format="csc")).tocsc()
            lu = self.factorise(a, "G - sigma M", sigma)
        del a
        self._shifted[sigma] = lu
        return lu, sigma, False

    def drop_shifted_factors(self) -> None:
        """Forget the cached factors of G - sigma M (:meth:`shifted_factor`): the next solve with
        inertia factorises afresh, as a new system of the same network would (a job that solves
        at a second time step keeps its system, and its record does not depend on the first)."""
        self._shifted.clear()

    def solve(
        self,
        kn,
        kt,
        omega: float,
        amplitude: float = HEAD_AMPLITUDE_M,
        inertia: str = "full",
        omega2: complex | None = None,
        axis: int = 0,
    ) -> HarmonicSolution:
        """Steady state for per-bond stiffnesses kn, kt (B,) complex N/m at w (rad/s).

        One complex sparse LU (SuperLU, symmetric mode, the system's ordering) per call: the
        general path, for bond laws that differ from bond to bond.

        Parameters
        ----------
        amplitude : float
            Head displacement amplitude A, m (paper: 63e-6).
        inertia : {"none", "full"}
            See the module docstring (masses in the dynamics, content of the force F).
        omega2 : complex, optional
            The factor of the mass matrix, -s^2 for the Laplace variable s (1/s^2); default
            w^2 (s = i w). See :meth:`solve_law` (``laplace``).
        axis : {0, 1, 2}
            Axis of the head displacement: 0 (x) bends the 2PB cantilever; 2 (z, along the
            specimen's height) compresses it, the uniaxial test (with ``head_rotation="clamped"``).

        Raises
        ------
        ValueError
            on an unknown option.
        """
        _check_inertia(inertia)
        t0 = time.perf_counter()
        if axis not in (0, 1, 2):
            raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
        blk = self.blocks(np.asarray(kn, complex), np.asarray(kt, complex))
        up = np.zeros(3, complex)
        up[axis] = amplitude
        omega2 = omega**2 if omega2 is None else omega2
        a_ff = blk["ff"]
        if inertia != "none":
            a_ff = (a_ff - omega2 * sp.diags(self.mass_free.astype(complex), format="csc")).tocsc()
        rhs = -(blk["fp"] @ up)
        uf = self.factorise(a_ff, "complex K - w^2 M").solve(rhs) if self.n_free else np.zeros(0, complex)
        residual = _relative_residual(a_ff, uf, rhs)
        reaction = blk["pf"] @ uf + blk["pp"] @ up
        return self._solution(omega, uf, reaction, amplitude, inertia, residual, t0, "direct", omega2=omega2, up=up)

    def solve_law(
        self,
        law,
        frequency_Hz: float,
        amplitude: float = HEAD_AMPLITUDE_M,
        inertia: str = "full",
        solver: str = "reuse",
        rtol: float = 1e-12,
        laplace: complex | None = None,
    ) -> HarmonicSolution:
        """Steady state with every bond following ``law`` scaled by a_b (Eqs. 30-33, 8-11).

        Parameters
        ----------
        law : object with ``complex_modulus(omega)`` (Pa), e.g. GeneralizedBurgers
            The macro law; every bond gets k_n = a_b E*(w), k_t = k_n / (2 (1 + nu)).
        frequency_Hz : float
            Test frequency f, Hz (w = 2 pi f).
        solver : {"reuse", "direct"}
            ``reuse``: K(w) - w^2 M = E*(w) (G - s M) with s = w^2 / E* and the real G
            independent of (T, f). Without inertia the solution is a back-substitution with
            G's factor (computed once per sample). With inertia, (G - s M) u = -G_fp u_p is
            solved by GMRES to the relative residual ``rtol``, preconditioned by the real
            factor of G - sigma M, sigma = Re(s) (:meth:`shifted_factor`: reused across
            (T, f) while sigma stays near, see :data:`SHIFT_REUSE_BELOW`); if GMRES has not
            converged after :data:`GMRES_MAX_ITERATIONS` iterations with a reused factor,
            G - Re(s) M is factorised and GMRES restarted; if that fails too the call falls
            back to ``direct`` (the solution's ``solver`` then reads "direct").
            ``direct``: one complex LU per call (:meth:`solve`).
        laplace : complex, optional
            Solve at the Laplace variable s instead of s = i w (1/s): every i w of the bond law
            and of the inertia becomes s, i.e. E*(w) -> E(s) (:func:`laplace_modulus`) and
            w^2 M -> -s^2 M. The time-discrete steady state of the Moreau-Jean theta-method
            at w is the solution at its effective Laplace variable
            (:func:`asphalt_nscd.harmonic.periodic.theta_laplace`). The solution's
            ``frequency_Hz`` stays ``frequency_Hz``.

        Raises
        ------
        ValueError
            on an unknown option, or a ``laplace`` off the imaginary axis with a law that is
            not a :class:`~asphalt_nscd.rheology.laws.GeneralizedBurgers`.
        """
        _check_inertia(inertia)
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}")
        omega = 2.0 * np.pi * float(frequency_Hz)
        omega2: float | complex
        if laplace is None:
            e = complex(law.complex_modulus(omega))
            omega2 = omega**2
        else:
            e = laplace_modulus(law, laplace)
            omega2 = -(complex(laplace) ** 2)
        if solver == "direct":
            kn = self.network.scale * e
            return self.solve(kn, kn * self.t_ratio, omega, amplitude=amplitude, inertia=inertia, omega2=omega2)
        t0 = time.perf_counter()
        up = np.array([amplitude, 0.0, 0.0], complex)
        uf = np.zeros(self.n_free, complex)
        residual = 0.0
        self.last_gmres_iterations = 0
        if inertia == "none":
            ref = self._reference()
            rhs = -(ref["fp"] @ up)
            if self.n_free:
                uf = ref["lu"].solve(rhs)
                residual = _relative_residual(ref["ff"], uf, rhs)
        else:
            ref = self._reference_blocks()
            rhs = -(ref["fp"] @ up)
            if self.n_free:
                s = complex(omega2 / e)
                uf, residual = self._gmres_shifted(ref["ff"], s, rhs, rtol)
                if uf is None:
                    return self.solve(
                        e * self.network.scale,
                        e * self.network.scale * self.t_ratio,
                        omega,
                        amplitude=amplitude,
                        inertia=inertia,
                        omega2=omega2,
                    )
        reaction = e * (ref["pf"] @ uf + ref["pp"] @ up)
        return self._solution(omega, uf, reaction, amplitude, inertia, residual, t0, "reuse", omega2=omega2)

    def _gmres_shifted(self, g, s, rhs, rtol):
        """Solve (G - s M) u = rhs by GMRES preconditioned with a real factor of G - sigma M.

        With sigma = Re(s) the preconditioned spectrum (lambda - s)/(lambda - sigma) over the
        eigenvalues lambda of (G, M) lies on the line Re z = 1: bounded away from 0, so
        GMRES needs few iterations whatever the distance to a resonance (module docstring).

        Returns (u, relative residual), or (None, nan) if GMRES did not converge.
        """
        m = self.mass_free
        op = spla.LinearOperator((self.n_free,) * 2, dtype=complex, matvec=lambda v: g @ v - s * (m * v.ravel()))
        rhs = rhs.astype(complex)
        x0 = None
        for attempt in range(2):
            lu, sigma, reused = self.shifted_factor(s.real, reuse=attempt == 0)
            prec = spla.LinearOperator(
                (self.n_free,) * 2, dtype=complex, matvec=lambda v, lu=lu: lu.solve(np.asarray(v).ravel())
            )
            if x0 is None:
                x0 = prec @ rhs
            count = [0]

            def tick(_, count=count):
                count[0] += 1

            restart = max(1, min(100, GMRES_MAX_ITERATIONS))
            # at least one restart: SciPy's GMRES stops a cycle on the preconditioned residual
            # and checks the true one only at the restart; without a restart a solution whose
            # true residual is just above rtol was rejected after 10 iterations and the call
            # fell back to the (slow) complex LU (theta-method steady states, campaign.periodic)
            uf, info = spla.gmres(
                op,
                rhs,
                x0=x0,
                rtol=rtol,
                atol=0.0,
                M=prec,
                restart=restart,
                maxiter=max(2, -(-GMRES_MAX_ITERATIONS // restart)),
                callback=tick,
                callback_type="pr_norm",
            )
            self.last_gmres_iterations += count[0]
            if info == 0:
                return uf, float(np.linalg.norm(op @ uf - rhs) / np.linalg.norm(rhs))
            x0 = uf
            if not reused:
                break
        return None, float("nan")

    def _solution(self, omega, uf, reaction, amplitude, inertia, residual, t0, solver, omega2=None, up=None):
        up = np.array([amplitude, 0.0, 0.0], complex) if up is None else up
        m_top = float(self.network.plate_mass[1])
        sample_mass = self.network.sample_mass
        mu = SPECIMEN_MASS_FACTOR * sample_mass + m_top
        omega2 = omega**2 if omega2 is None else omega2
        force = reaction - omega2 * (m_top if inertia == "full" else mu) * up
        d = self.dof_per_sphere
        n_act = int(self.active.sum())
        q = np.asarray(uf)[: d * n_act].reshape(-1, d)
        disp = np.zeros((self.network.n_spheres, 3), complex)
        rot = np.zeros((self.network.n_spheres, 3), complex)
        disp[self.active] = q[:, :3]
        if d == 6:
            rot[self.active] = q[:, 3:]
        head = np.zeros(3, complex)
        if self.head_rotation == "free":
            head = np.asarray(uf)[d * n_act : d * n_act + 3]
        return HarmonicSolution(
            frequency_Hz=omega / (2 * np.pi),
            force=force,
            reaction=reaction,
            displacement=disp,
            amplitude_m=amplitude,
            mu_kg=mu,
            sample_mass_kg=sample_mass,
            plate_mass_kg=m_top,
            inertia=inertia,
            n_free_dof=self.n_free,
            n_load_free=self.n_load_free,
            solve_time_s=time.perf_counter() - t0,
            residual=residual,
            solver=solver,
            rotation=rot,
            head_rotation=head,
        )


def laplace_modulus(law, s: complex) -> complex:
    """Modulus E(s) of a law at the Laplace variable s (1/s), Pa.

    ``s = i w`` (w > 0) gives the complex modulus E*(w) (``law.complex_modulus``, any law
    object). Off the imaginary axis the law must be a generalized Burger's model (fields
    ``Em, eta_m, Ek, eta_k, E_inf``): E(s) = E_inf + [1/Em + 1/(s eta_m) + sum_i
    1/(Ek[i] + s eta_k[i])]^-1 (rheology.laws.GeneralizedBurgers with i w -> s).

    Raises
    ------
    ValueError
        if s is off the imaginary axis and the law has no generalized Burger's fields.
    """
    s = complex(s)
    if s.real == 0.0 and s.imag > 0.0:
        return complex(law.complex_modulus(s.imag))
    if not all(hasattr(law, k) for k in ("Em", "eta_m", "Ek", "eta_k", "E_inf")):
        raise ValueError(
            f"laplace_modulus: s = {s} is off the imaginary axis and the law "
            f"{type(law).__name__} is not a generalized Burger's model"
        )
    d = 1.0 / law.Em + (0.0 if np.isinf(law.eta_m) else 1.0 / (s * law.eta_m))
    for ek, ck in zip(law.Ek, law.eta_k):
        d += 1.0 / (ek + s * ck)
    return complex(law.E_inf + 1.0 / d)


def _lever(arm) -> np.ndarray:
    """(B, 6, 6) maps [[I, -skew(arm)], [0, I]]: (u, theta) -> (u + theta x arm, theta)."""
    out = np.zeros((len(arm), 6, 6))
    out[:, :3, :3] = np.eye(3)
    out[:, 3:, 3:] = np.eye(3)
    x, y, z = arm[:, 0], arm[:, 1], arm[:, 2]
    # -skew(arm) = [[0, z, -y], [-z, 0, x], [y, -x, 0]]
    out[:, 0, 4], out[:, 0, 5] = z, -y
    out[:, 1, 3], out[:, 1, 5] = -z, x
    out[:, 2, 3], out[:, 2, 4] = y, -x
    return out


def _fill(lu) -> int:
    """L.nnz + U.nnz of a SuperLU factor (SciPy copies L and U at each access: one at a time)."""
    n = int(lu.L.nnz)
    return n + int(lu.U.nnz)


def _check_inertia(inertia: str) -> None:
    if inertia not in INERTIA_MODES:
        raise ValueError(f"inertia must be one of {INERTIA_MODES}, got {inertia!r}")


def _relative_residual(a, x, b) -> float:
    norm_b = np.linalg.norm(b)
    return float(np.linalg.norm(a @ x - b) / norm_b) if norm_b > 0 else 0.0


def held_spheres(
    sample, bond_kinematics: str = "contact", head_rotation: str = "free", nu: float = POISSON_RATIO
) -> np.ndarray:
    """Mask (N,) of the spheres the bond network holds: every sphere but (1) the spheres no
    chain of bonds ties to a plate (a sphere or a cluster floating inside the sample: it carries
    no load in the test and, under gravity, falls through the sample -- 3 mm in the 25 ms of a
    40 Hz cycle -- into spheres it then pushes) and (2) the dangling mechanisms of the
    ``contact`` kinematics, the clusters of weakly held spheres
    (:meth:`asphalt_nscd.harmonic.solver.HarmonicSystem.mechanism_modes`) that hang by a
    single bond from the rest of the sample (a sphere held by one bond, a pair held by one),
    found again after each removal until none is left. Such a cluster carries no load in the
    linear test (nothing passes through it), and under gravity its linearised bond lets it
    turn without limit about the bond's contact point (a pendulum without a restoring force:
    about 400 rad in 0.35 s for a 2 mm sphere), through its neighbours. A weakly held sphere
    on a load path (two bonds, a chain link) stays: its only zero mode is a spin about the
    line through its bonds (``campaign.test.mechanisms`` says how its weight meets it). The
    ``barycentre`` kinematics has no mechanisms; its floating spheres are dropped too."""
    from ..sample.store import subsample
    from .network import network_from_sample

    keep = np.ones(sample.radius.size, bool)
    while True:
        sub = subsample(sample, keep)
        network = network_from_sample(sub)
        system = HarmonicSystem(
            network,
            nu=nu,
            bond_kinematics=bond_kinematics,
            head_rotation=head_rotation,
            regularisation=0.0,
        )
        i, j = sub.bonds["i"], sub.bonds["j"]
        dropped = [np.flatnonzero(~system.active)]  # no chain of bonds to a plate
        if bond_kinematics != "contact":
            modes = []
        else:
            modes = system.mechanism_modes()
        for _, _, _, spheres in modes:
            inside = np.zeros(sub.radius.size, bool)
            inside[spheres] = True
            external = inside[i] != ((j >= 0) & inside[np.maximum(j, 0)])  # one end in the cluster
            if int(external.sum()) <= 1:
                dropped.append(spheres)
        if not sum(len(d) for d in dropped):
            return keep
        keep[np.flatnonzero(keep)[np.concatenate(dropped)]] = False
