"""Global transforms of every link and joint frame along the spanning tree.

T_0^(0) = E; for a tree joint from parent link i to child link j,
T_j^(0) = T_i^(0) T_j^(i) with T_j^(i) = T_ik^(i) T_jm^(ik) (T_jm^(j))^-1, or its inverse
when the coupling row names the child first. Everything stays symbolic in the joint
variables and the parameters.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from csim.linkage.tables import Tables
from csim.linkage.topology import Topology
from csim.linkage.transforms import frame_transform, inverse, joint_transform, link_to_link, simplify_matrix
from csim.model.deferred import DeferredFields


@dataclass
class Frames(DeferredFields):
    """Symbolic transforms (pickled as one blob, unpickled where first read:
    :class:`csim.model.deferred.DeferredFields`).

    Attributes
    ----------
    local : dict (link, joint) -> Matrix (4, 4)
        T_ik^(i): joint frame k in its link frame.
    joints : dict coupling number -> Matrix (4, 4)
        T_jm^(ik) of each tree joint, in its joint variables.
    relative : dict child link -> Matrix (4, 4)
        T_child^(parent) across its tree joint.
    links : dict link -> Matrix (4, 4)
        T_i^(0), global transform of each link.
    """

    local: dict[tuple[int, int], sp.Matrix]
    joints: dict[int, sp.Matrix]
    relative: dict[int, sp.Matrix]
    links: dict[int, sp.Matrix]
    _global: dict[tuple[int, int], sp.Matrix] = field(default_factory=dict, repr=False)

    DEFERRED = ("local", "joints", "relative", "links", "_global")

    def joint_frame(self, link: int, index: int) -> sp.Matrix:
        """T_ik^(0) = T_i^(0) T_ik^(i), (4, 4)."""
        key = (link, index)
        if key not in self._global:
            self._global[key] = simplify_matrix(self.links[link] * self.local[key])
        return self._global[key]


def build_frames(tables: Tables, topology: Topology) -> Frames:
    """All transforms of the mechanism (see the module docstring)."""
    local = {(n, f.index): frame_transform(f.p) for n, link in tables.links.items() for f in link.joints}
    joints, relative = {}, {}
    links = {0: sp.eye(4)}
    for child in topology.order[1:]:
        edge = topology.edges[child]
        c = edge.coupling
        q = [v.symbol for v in topology.variables_of(c)]
        T_joint = joint_transform(c.type, q)
        joints[c.number] = T_joint
        T_ji = link_to_link(local[(c.i, c.k)], T_joint, local[(c.j, c.m)])  # link j in link i
        relative[child] = T_ji if edge.forward else simplify_matrix(inverse(T_ji))
        links[child] = simplify_matrix(links[edge.parent] * relative[child])
    return Frames(local=local, joints=joints, relative=relative, links=links)
