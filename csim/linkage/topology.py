"""Structure of a mechanism: spanning tree, chain substructures, cut joints, joint variables.

The links are the nodes and the couplings the edges of a graph. A spanning tree rooted at
the fixed link 0 is grown edge by edge (Kruskal), taking the couplings in this order:
driven joints first (they need joint variables), then by the cut preference of their type
(:data:`csim.linkage.joints.JOINT_TYPES`: R and P, then C, U and S, the ones the paper
prefers to cut), each group in table order. A coupling that would
close a loop is cut: it gets no joint variable, it contributes constraint equations.

The tree is split into chains (the paper's substructures): each chain starts at the root or
at a branching link and follows, at every link, the child reached by the first coupling of
the table; the other children start new chains. Joint variables are numbered along the
chains in this order, so that the paper's 3-RRR robot gets q1, q2, q3 on 0-1-2-7, q4, q5 on
0-3-4 and q6, q7 on 0-5-6.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from csim.errors import CaseError
from csim.linkage.joints import JOINT_TYPES
from csim.linkage.tables import Coupling, Tables


@dataclass(frozen=True)
class JointVariable:
    """One joint variable of a tree joint.

    Attributes
    ----------
    symbol, velocity : sympy Symbol
    coupling : Coupling
    slot : int
        0-based index among the joint's variables.
    unit : str
    meaning : str
    """

    symbol: sp.Symbol
    velocity: sp.Symbol
    coupling: Coupling
    slot: int
    unit: str
    meaning: str

    @property
    def name(self) -> str:
        return str(self.symbol)


@dataclass(frozen=True)
class TreeEdge:
    """A tree joint seen from the root: ``parent`` -> ``child`` through ``coupling``.

    ``forward`` is True when the coupling row reads (parent, k, child, m), False when it
    reads (child, ., parent, .) and the link-to-link transform is inverted.
    """

    parent: int
    child: int
    coupling: Coupling
    forward: bool


@dataclass
class Topology:
    """Spanning tree, substructures, cut joints and joint variables.

    Attributes
    ----------
    edges : dict child link -> TreeEdge
    order : list of int
        Links from the root, each after its parent.
    chains : list of list of int
        Substructures: link sequences, each starting at the root or a branching link.
    tree_joints, cut_joints : list of Coupling
    variables : list of JointVariable
        In chain order.
    """

    edges: dict[int, TreeEdge]
    order: list[int]
    chains: list[list[int]]
    tree_joints: list[Coupling]
    cut_joints: list[Coupling]
    variables: list[JointVariable]

    def variables_of(self, coupling: Coupling) -> list[JointVariable]:
        return [v for v in self.variables if v.coupling.number == coupling.number]


def _variable_names(coupling: Coupling, counter: int) -> list[str]:
    """Readable names: q<n> (paper numbering) for unnamed joints; from the name and the
    type's templates otherwise (q_J, s_J, q_J_1, ...)."""
    if coupling.name is None:
        return [f"q{counter + s}" for s in range(coupling.freedoms)]
    return JOINT_TYPES[coupling.type].variable_names(coupling.name)


def _joint_variables(tables: Tables, chains: list[list[int]], edges: dict[int, TreeEdge]) -> list[JointVariable]:
    """The joint variables of the tree joints, numbered along the chains; their units and
    meanings from the joint types' records.

    Raises
    ------
    CaseError
        A variable (or its velocity NAME_dot) has the name of a parameter or of another variable.
    """
    variables: list[JointVariable] = []
    taken = set(tables.symbols)
    problems = []
    for chain in chains:
        for child in chain[1:]:
            c = edges[child].coupling
            names = _variable_names(c, len(variables) + 1)
            for slot, name in enumerate(names):
                # the variable and its velocity NAME_dot become symbols: neither may be a parameter's
                clash = {name, f"{name}_dot"} & taken
                if clash:
                    problems.append(f"{c.path}: its joint variable {name!r} (velocity {name + '_dot'!r}) has the "
                                    f"name of a parameter or of another joint variable ({', '.join(sorted(clash))}); "
                                    f"expected the coupling name or the parameter renamed")
                    continue
                taken |= {name, f"{name}_dot"}
                spec = JOINT_TYPES[c.type].variables[slot]
                variables.append(JointVariable(sp.Symbol(name, real=True), sp.Symbol(f"{name}_dot", real=True), c,
                                               slot, spec.unit, spec.meaning))
    if problems:
        raise CaseError(problems)
    return variables


def analyse(tables: Tables, driven: set[int]) -> Topology:
    """Find the spanning tree, the chains, the cut joints and the joint variables.

    Parameters
    ----------
    tables : Tables
    driven : set of int
        Numbers of the couplings whose variables are prescribed (kept in the tree).

    Raises
    ------
    CaseError
        Links not connected to the fixed link, or joint-variable names clashing with
        parameter names.
    """
    links = sorted(tables.links)
    root_of = {n: n for n in links}

    def find(n):
        while root_of[n] != n:
            root_of[n] = root_of[root_of[n]]
            n = root_of[n]
        return n

    ranked = sorted(tables.couplings,
                    key=lambda c: (0 if c.number in driven else 1, JOINT_TYPES[c.type].cut_preference, c.number))
    tree, cut = [], []
    for c in ranked:
        a, b = find(c.i), find(c.j)
        if a == b:
            cut.append(c)
        else:
            root_of[a] = b
            tree.append(c)
    loose = [n for n in links if find(n) != find(0)]
    if loose:
        raise CaseError([
            f"{tables.links[n].path} ({tables.link_label(n)}): not connected to the fixed link 0 through "
            f"mechanism.couplings; expected a chain of couplings from link 0 to every link" for n in loose])
    tree.sort(key=lambda c: c.number)
    cut.sort(key=lambda c: c.number)

    # orient the tree from the root; children in table order
    children: dict[int, list[tuple[int, Coupling]]] = {n: [] for n in links}
    adjacency: dict[int, list[tuple[int, Coupling]]] = {n: [] for n in links}
    for c in tree:
        adjacency[c.i].append((c.j, c))
        adjacency[c.j].append((c.i, c))
    edges: dict[int, TreeEdge] = {}
    order = [0]
    seen = {0}
    stack = [0]
    while stack:
        parent = stack.pop(0)
        for child, c in sorted(adjacency[parent], key=lambda x: x[1].number):
            if child in seen:
                continue
            seen.add(child)
            edges[child] = TreeEdge(parent, child, c, forward=(c.i == parent))
            children[parent].append((child, c))
            order.append(child)
            stack.append(child)

    chains: list[list[int]] = []

    def emit(start: int, first: int):
        chain = [start, first]
        while children[chain[-1]]:
            chain.append(children[chain[-1]][0][0])
        chains.append(chain)
        for n, link in enumerate(chain):
            branches = children[link][1:] if n > 0 else []
            for child, _ in branches:
                emit(link, child)

    for child, _ in children[0]:
        emit(0, child)

    variables = _joint_variables(tables, chains, edges)
    return Topology(edges=edges, order=order, chains=chains, tree_joints=tree, cut_joints=cut, variables=variables)


def grubler_kutzbach(tables: Tables, planar: bool) -> int:
    """Mobility count: 6 (n - 1) - sum (6 - f), or 3 (n - 1) - sum (3 - f) for planar mechanisms.

    n counts the links (the fixed one included), f the freedoms of each joint.
    """
    lam = 3 if planar else 6
    n = len(tables.links)
    return lam * (n - 1) - sum(lam - c.freedoms for c in tables.couplings)


def subtree(topology: Topology, child: int) -> set[int]:
    """The links beyond a tree joint: ``child`` and every link reached from it away from link 0."""
    below = {child}
    for link in topology.order:
        edge = topology.edges.get(link)
        if edge is not None and edge.parent in below:
            below.add(link)
    return below
