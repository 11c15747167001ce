"""Link-coupling input: a mechanism from its links and couplings tables (docs/link-coupling.md).

The tables (:mod:`csim.linkage.tables`), joint types (:mod:`csim.linkage.joints`), the tree
and cut joints (:mod:`csim.linkage.topology`), the constraint equations and the model
(:mod:`csim.linkage.model`), force elements (:mod:`csim.linkage.forces`), joint reactions
(:mod:`csim.linkage.reactions`) and kinematic analysis (:mod:`csim.linkage.kinematics`).
"""
