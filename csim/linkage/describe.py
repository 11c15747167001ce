"""``csim describe``: what csim derives from a link-coupling description, as text, LaTeX or JSON.

The report lists the chain substructures, the cut joints, the joint variables, the global
transforms of the links, the independent constraint equations (and which ones were removed,
and why), the degrees of freedom, the reaction unknowns of every cut joint, what a run does
(forward dynamics, kinematic analysis or driven dynamics: ``mechanism.drive_mode``) and the
force elements (``mechanism.forces``) with what csim derived for each: its potential and its
loads (generalized direction, law, switching).
"""
from __future__ import annotations

import json

import sympy as sp

from csim.errors import CaseError
from csim.linkage.constraints import DEPENDENT, ZERO
from csim.linkage.joints import JOINT_TYPES
from csim.linkage.model import Linkage

#: what a run of the mechanism is, by ``mechanism.drive_mode`` (None: no drive)
RUN_KINDS = {
    None: "forward dynamics (no mechanism.drive): the motion under the masses, gravity and force elements",
    "kinematic": "kinematic analysis (mechanism.drive, drive_mode kinematic): the motion prescribed by the drives, "
                 "no forces",
    "dynamic": "driven dynamics (mechanism.drive, drive_mode dynamic): the drives are rheonomic constraints, the "
               "joints not driven move freely; the torques and forces the drives need are recorded (forces/drive)",
}


def drive_mode(linkage: Linkage, mechanism: dict) -> str | None:
    """The run's drive mode: None without drives, else ``mechanism.drive_mode`` (default kinematic)."""
    return (mechanism.get("drive_mode") or "kinematic") if linkage.drive else None


def _link_name(linkage: Linkage, n: int) -> str:
    link = linkage.tables.links[n]
    return f"{n} ({link.name})" if link.name else str(n)


def report(linkage: Linkage, links: list[int] | None = None, mode: str | None = "", latex: bool = True) -> dict:
    """Everything the report shows, as plain data (strings for expressions).

    Parameters
    ----------
    linkage : Linkage
    links : list of int, optional
        Links whose global transforms are listed (default: every moving link).
    mode : str or None, optional
        The drive mode (:func:`drive_mode`); "" (default): kinematic when there are drives.
    latex : bool, optional
        Also print every expression as LaTeX (the ``latex`` entries; "" without). The
        plain text needs none, and printing a long chain's transforms as LaTeX takes more
        than half of ``csim describe``'s time.

    Raises
    ------
    CaseError
        A requested link does not exist.
    """
    tables, topo, red = linkage.tables, linkage.topology, linkage.reduction
    chosen = links if links else [n for n in sorted(tables.links) if n != 0]
    bad = [n for n in chosen if n not in tables.links]
    if bad:
        raise CaseError([f"--link {bad[0]}: no such link; expected one of {', '.join(map(str, sorted(tables.links)))}"])
    chains = []
    for chain in topo.chains:
        joints = [topo.edges[child].coupling for child in chain[1:]]
        chains.append({"links": chain, "joints": [c.number for c in joints],
                       "variables": [v.name for c in joints for v in topo.variables_of(c)]})
    variables = [{"name": v.name, "unit": v.unit, "joint": v.coupling.number, "joint_name": v.coupling.name,
                  "type": v.coupling.type, "meaning": v.meaning, "start": linkage.start[v.name],
                  "driven": v.name in linkage.drive,
                  "drive": linkage.drive_source.get(v.name) if v.name in linkage.drive else None}
                 for v in topo.variables]
    kept = red.kept
    tex = sp.latex if latex else (lambda expr: "")
    constraints = [{"expression": str(e.expression), "latex": tex(e.expression), "joint": e.coupling.number,
                    "component": e.component, "reaction": e.reaction} for e in kept]
    removed = [{"expression": str(e.expression), "joint": e.coupling.number, "component": e.component,
                "why": e.status} for e in red.equations if e.status != "kept"]
    cut = []
    for c in topo.cut_joints:
        eqs = [e for e in red.equations if e.coupling.number == c.number]
        cut.append({"number": c.number, "name": c.name, "type": c.type, "between": [[c.i, c.k], [c.j, c.m]],
                    "equations": len(eqs), "kept": sum(e.status == "kept" for e in eqs),
                    "identically_zero": sum(e.status == ZERO for e in eqs),
                    "dependent": sum(e.status == DEPENDENT for e in eqs),
                    "reactions": JOINT_TYPES[c.type].reactions,
                    "reaction_unknowns": [e.reaction for e in eqs if e.status == "kept"]})
    transforms = {str(n): {"name": tables.links[n].name, "matrix": [[str(x) for x in row] for row in
                                                                    linkage.frames.links[n].tolist()],
                           "latex": tex(linkage.frames.links[n])} for n in chosen}
    return {
        "mechanism": tables.label,
        "links": len(tables.links),
        "joints": len(tables.couplings),
        "planar": linkage.planar,
        "substructures": chains,
        "tree_joints": [c.number for c in topo.tree_joints],
        "cut_joints": cut,
        "joint_variables": variables,
        "transforms": transforms,
        "constraints": constraints,
        "removed_equations": removed,
        "dof": {"grubler_kutzbach": linkage.grubler, "formula": "planar" if linkage.planar else "spatial",
                "actual": linkage.dof, "joint_variables": len(variables), "rank": red.generic_rank,
                "rank_at_start": red.rank_at_start, "overconstrained": linkage.dof > linkage.grubler,
                "configurations_sampled": red.samples},
        "notes": list(linkage.notes),
        "drive_mode": (("kinematic" if linkage.drive else None) if mode == "" else mode),
        "run": RUN_KINDS[("kinematic" if linkage.drive else None) if mode == "" else mode],
        "forces": [_element(e, tex) for e in linkage.forces.elements],
    }


def _load(load, tex=sp.latex) -> dict:
    """A load of a force element: what it acts along, its law and switching, as strings."""
    window = [w if abs(w) != float("inf") else str(w) for w in load.window]
    return {"name": load.name, "unit": load.unit, "description": load.description,
            "coordinate": str(load.coordinate), "coordinate_unit": load.coordinate_unit,
            "law": str(load.law if load.law is not None else 1), "latex": tex(load.law if load.law is not None
                                                                              else sp.Integer(1)),
            "direction": None if load.direction is None else [str(d) for d in load.direction],
            "window": window, "velocity": load.velocity}


def _element(record, tex=sp.latex) -> dict:
    """A force element as written and what csim derived from it."""
    return {"name": record.name, "type": record.kind, "row": record.row,
            "potential": str(record.potential), "potential_latex": tex(record.potential),
            "loads": [_load(ld, tex) for ld in record.loads]}


def _text(data: dict, linkage: Linkage) -> str:
    tables = linkage.tables
    out = [f"Link-coupling mechanism {data['mechanism']!r}: {data['links']} links, {data['joints']} joints"
           f"{' (planar)' if data['planar'] else ''}", "", "Substructures (chains from the fixed link 0):"]
    for n, chain in enumerate(data["substructures"], 1):
        links = " - ".join(_link_name(linkage, x) for x in chain["links"])
        out.append(f"  {n}: {links}   joints {', '.join(map(str, chain['joints']))}   "
                   f"variables {', '.join(chain['variables'])}")
    cuts = ", ".join(f"{c['number']}{' ' + c['name'] if c['name'] else ''} ({c['type']}, "
                     f"({c['between'][0][0]},{c['between'][0][1]})-({c['between'][1][0]},{c['between'][1][1]}))"
                     for c in data["cut_joints"]) or "none (a tree)"
    out += ["", f"Cut joints: {cuts}", "", f"Joint variables ({len(data['joint_variables'])}):"]
    width = max((len(v["name"]) for v in data["joint_variables"]), default=1)
    for v in data["joint_variables"]:
        c = next(c for c in tables.couplings if c.number == v["joint"])
        drive = f"   driven: {v['drive']}" if v["driven"] else ""
        out.append(f"  {v['name']:<{width}} [{v['unit']}]  {c.label}: {v['meaning']}; "
                   f"at the start {v['start']:.6g}{drive}")
    out += ["", "Global transforms T_i^(0) (rotation | origin [m]):"]
    for n, t in data["transforms"].items():
        out.append(f"  T_{_link_name(linkage, int(n))} =")
        for row in t["matrix"]:
            out.append("    [" + ", ".join(row) + "]")
    zero = sum(1 for e in data["removed_equations"] if e["why"] == ZERO)
    dep = sum(1 for e in data["removed_equations"] if e["why"] == DEPENDENT)
    total = len(data["constraints"]) + len(data["removed_equations"])
    out += ["", f"Constraint equations: {total} generated by the cut joints, {zero} hold identically, {dep} "
                f"dependent, {len(data['constraints'])} independent:"]
    for n, e in enumerate(data["constraints"], 1):
        out.append(f"  ({n}) [joint {e['joint']}, {e['component']}]  {e['expression']} = 0")
    if data["removed_equations"]:
        out.append("  removed:")
        for e in data["removed_equations"]:
            out.append(f"    [joint {e['joint']}, {e['component']}] {e['why']}"
                       + (f": {e['expression']}" if e["why"] == DEPENDENT else ""))
    d = data["dof"]
    out += ["", f"Degrees of freedom: Grubler-Kutzbach count ({d['formula']}) {d['grubler_kutzbach']}; actual "
                f"{d['actual']} = {d['joint_variables']} joint variables - rank {d['rank']} of the constraint "
                f"Jacobian (generic, over {d['configurations_sampled']} assembled configurations)"]
    if d["overconstrained"]:
        out.append(f"  overconstrained: the mechanism moves with {d['actual']} DOF although the count gives "
                   f"{d['grubler_kutzbach']} (special geometry; the dependent equations were removed)")
    if d["rank_at_start"] < d["rank"]:
        out.append(f"  the rank drops to {d['rank_at_start']} at the given configuration (a singular position)")
    out += ["", "Reaction unknowns per cut joint (joint frame ik; one multiplier per independent equation):"]
    for c in data["cut_joints"]:
        out.append(f"  joint {c['number']} {c['type']}: {', '.join(c['reactions'])}; independent: "
                   f"{', '.join(c['reaction_unknowns']) or 'none'}")
    out += ["", f"Run: {data['run']}"]
    out += _forces_text(data["forces"])
    if data["notes"]:
        out += ["", "Notes:"] + [f"  {note}" for note in data["notes"]]
    return "\n".join(out) + "\n"


def _forces_text(forces: list[dict]) -> list[str]:
    """The force elements: each as written, its potential V [J] and its loads u b(q)."""
    out = ["", f"Force elements ({len(forces)}){':' if forces else ': none (mechanism.forces)'}"]
    for e in forces:
        keys = ", ".join(f"{k}: {v}" for k, v in e["row"].items())
        out.append(f"  {e['name']} ({e['type']}): {keys}")
        if e["potential"] != "0":
            out.append(f"    potential V = {e['potential']} [J]")
        for ld in e["loads"]:
            along = (f"along d({ld['coordinate']})/dq" if ld["direction"] is None else
                     f"generalized direction [{', '.join(ld['direction'])}]")
            switch = "" if ld["window"] == ["-inf", "inf"] and ld["velocity"] == "any" else (
                f"; active while s = {ld['coordinate']} [{ld['coordinate_unit']}] is in {ld['window']}"
                f"{'' if ld['velocity'] == 'any' else ' and ds/dt is ' + ld['velocity']}")
            out.append(f"    load {ld['name']} [{ld['unit']}] = {ld['law']}, {along}{switch}")
    return out


def _latex(data: dict, linkage: Linkage) -> str:
    out = [f"% csim describe: link-coupling mechanism {data['mechanism']}",
           r"\paragraph{Joint variables} $" + ", ".join(sp.latex(v.symbol) for v in linkage.topology.variables)
           + "$", r"\paragraph{Global transforms}", r"\begin{align}"]
    rows = [f"T_{{{n}}}^{{(0)}} &= {t['latex']}" for n, t in data["transforms"].items()]
    out.append(" \\\\\n".join(rows))
    out += [r"\end{align}", r"\paragraph{Independent constraint equations}", r"\begin{align}"]
    out.append(" \\\\\n".join(f"{e['latex']} &= 0" for e in data["constraints"]) or "&")
    d = data["dof"]
    out += [r"\end{align}",
            rf"\paragraph{{Degrees of freedom}} Grubler--Kutzbach ({d['formula']}): {d['grubler_kutzbach']}; "
            rf"actual: {d['actual']} ({d['joint_variables']} joint variables, rank {d['rank']})."]
    out.append(rf"\paragraph{{Run}} {data['run']}.")
    if data["forces"]:
        out += [r"\paragraph{Force elements} potentials $V_e$ [J] and load laws $u$ (N or N m)", r"\begin{align}"]
        def tex(name: str) -> str:
            return name.replace("_", r"\_")

        rows = [rf"V_{{\mathrm{{{tex(e['name'])}}}}} &= {e['potential_latex']}" for e in data["forces"]
                if e["potential"] != "0"]
        rows += [rf"u_{{\mathrm{{{tex(ld['name'])}}}}} &= {ld['latex']}" for e in data["forces"]
                 for ld in e["loads"]]
        out += [" \\\\\n".join(rows) or "&", r"\end{align}"]
    return "\n".join(out) + "\n"


def describe_case(linkage: Linkage, latex: bool = False, as_json: bool = False, links: list[int] | None = None,
                  mode: str | None = "") -> str:
    """The report of a derived link-coupling model: text, LaTeX (``latex``) or JSON (``as_json``);
    ``mode`` as :func:`report`."""
    data = report(linkage, links, mode, latex=latex or as_json)
    if as_json:
        return json.dumps(data, indent=2) + "\n"
    if latex:
        return _latex(data, linkage)
    return _text(data, linkage)
