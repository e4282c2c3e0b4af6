"""Fill-reducing ordering of the harmonic system: METIS nested dissection of the body graph.

The stiffness matrix of the bonded network has one dense d x d block (d = 6 with the
``contact`` kinematics, 3 with ``barycentre``) per pair of bonded bodies, so its graph is the
sphere/bond graph with every node expanded to d unknowns. METIS nested dissection
(``pymetis.nested_dissection``, Karypis & Kumar 1998, SIAM J. Sci. Comput. 20(1):359-392) of
the body graph, expanded to the blocks, is a fill-reducing ordering that SciPy does not offer;
SuperLU then factorises the permuted matrix with ``permc_spec="NATURAL"``
(:func:`asphalt_nscd.nscd.linear.splu_symmetric` with ``permutation``).
Measured gains: :mod:`.solver` module docstring and docs/choices.md.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: Orderings of :func:`fill_reducing_ordering`: METIS nested dissection, or SuperLU's own
#: minimum degree on A^T + A (the previous default, kept for comparison).
ORDERINGS = ("metis", "mmd")


def nested_dissection(n_nodes: int, edge_i, edge_j, seed: int = 0) -> np.ndarray:
    """METIS nested-dissection ordering of an undirected graph.

    Parameters
    ----------
    n_nodes : int
        Number of nodes (0..n_nodes-1).
    edge_i, edge_j : (E,) int
        Edges; duplicates, both directions and self-loops are allowed (removed here).
    seed : int
        METIS random seed (the ordering is deterministic for a given seed).

    Returns
    -------
    (n_nodes,) int64 permutation: position k of the new order holds old node ``perm[k]``.
    """
    import pymetis

    edge_i = np.asarray(edge_i, np.int64)
    edge_j = np.asarray(edge_j, np.int64)
    off = edge_i != edge_j
    rows = np.concatenate([edge_i[off], edge_j[off]])
    cols = np.concatenate([edge_j[off], edge_i[off]])
    graph = sp.csr_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(n_nodes,) * 2)
    graph.sum_duplicates()
    graph.sort_indices()
    options = pymetis.Options(seed=int(seed))
    adjacency = pymetis.CSRAdjacency(graph.indptr.astype(np.int32), graph.indices.astype(np.int32))
    metis_perm, _ = pymetis.nested_dissection(adjacency, options=options)
    perm = np.asarray(metis_perm, np.int64)
    if np.any(np.sort(perm) != np.arange(n_nodes)):
        raise RuntimeError("METIS returned an invalid permutation")
    return perm


def expand_blocks(node_perm, node_start) -> np.ndarray:
    """Expand a node permutation to the unknowns of the nodes.

    Parameters
    ----------
    node_perm : (n,) int — node order (output of :func:`nested_dissection`).
    node_start : (n + 1,) int — unknowns of node k are node_start[k]:node_start[k+1].

    Returns
    -------
    (node_start[-1],) int64 permutation of the unknowns, nodes kept contiguous.
    """
    node_perm = np.asarray(node_perm, np.int64)
    node_start = np.asarray(node_start, np.int64)
    size = np.diff(node_start)[node_perm]
    first = node_start[node_perm]
    offset = np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)
    return np.repeat(first, size) + offset
