"""Stabilization methods as plug-ins: one class in one file runs on both backends.

The method defined here (a velocity penalty, gamma* = gamma - c Phi') is not part of csim.
Registered, it is a valid ``stabilization.method``, its option is a schema key, and the
compiled kernels call its gamma* through the generated dispatch: both backends take the
same steps and give the same motion. Exact integration gives Phi'' = -c Phi', so
Phi'(t) = Phi'(0) exp(-c t): checked against that closed form.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import CONFIGS

from csim.case import load_case
from csim.physics.jit import kernel
from csim.pipeline import run_case
from csim.solver import methods
from csim.solver.methods.base import Method, option


@kernel
def velocity_penalty_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out):
    """gamma*_i = gamma_i - c_i Phi'_i."""
    for i in range(r):
        out[i] = gamma[i] - gains[i] * phi_dot[i]


@dataclasses.dataclass(frozen=True)
class VelocityPenaltyOptions:
    penalty_c: object = option(5.0, "rate of decay of Phi'", "1/s", gain=True)


class VelocityPenalty(Method):
    name = "velocity_penalty"
    Options = VelocityPenaltyOptions
    compiled = True
    gamma_star_kernel = staticmethod(velocity_penalty_gamma_star)

    def __init__(self, penalty_c=5.0):
        super().__init__(penalty_c=penalty_c)
        self.c = penalty_c

    def gains(self, r):
        return [np.broadcast_to(np.asarray(self.c, dtype=float), (r,))]


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setattr(methods, "STABILIZERS", dict(methods.STABILIZERS))
    import csim.case
    import csim.fast.module
    import csim.fast.support

    for module in (csim.case, csim.fast.module, csim.fast.support):
        monkeypatch.setattr(module, "STABILIZERS", methods.STABILIZERS)
    methods.register(VelocityPenalty)
    field = methods.option_field(VelocityPenalty, dataclasses.fields(VelocityPenaltyOptions)[0])
    monkeypatch.setitem(csim.case.SCHEMA.fields["stabilization"].fields, "penalty_c", field)
    monkeypatch.setitem(csim.case.SETTABLE, "stabilization.penalty_c", field)
    return VelocityPenalty


def test_registry_lists_the_builtin_methods_in_rank_order():
    assert list(methods.STABILIZERS) == ["none", "baumgarte", "sliding_mode", "projection", "ggl",
                                         "augmented_lagrangian", "minimal"]
    with pytest.raises(KeyError, match="valid names: none, baumgarte"):
        methods.make_stabilizer("penalty")


def test_schema_keys_come_from_the_methods_options():
    fields = methods.schema_fields()
    assert fields["w"].default == 10.0 and fields["w"].unit == "1/s"
    assert fields["k"].default == 1e-6  # one default, in one place
    assert fields["projection_max_iter"].type == "integer" and fields["projection_max_iter"].ge == 1
    assert fields["switching"].choices == ("sgn", "sat", "tanh", "atan", "sqrt")


def test_docs_table_is_the_generated_one():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "how-it-works.md").read_text()
    assert methods.settings_table() in page


def test_a_method_in_one_file_runs_on_both_backends(registered):
    sets = ["stabilization.method=velocity_penalty", "stabilization.penalty_c=8", "initial.qd_offset={y: 0.02}",
            "simulation.t_end=1", "simulation.rtol=1e-10", "simulation.atol=1e-12"]
    fast = run_case(load_case(CONFIGS / "pendulum.yaml", [*sets, "simulation.backend=compiled"]))
    slow = run_case(load_case(CONFIGS / "pendulum.yaml", [*sets, "simulation.backend=python"]))
    same = run_case(load_case(CONFIGS / "pendulum.yaml", [*sets, "simulation.backend=interpreted"]))
    assert (fast.backend, slow.backend, same.backend) == ("compiled", "python", "interpreted")
    assert fast.ok and slow.ok and same.ok, (fast.message, slow.message, same.message)
    assert (fast.nfev, fast.nsteps) == (slow.nfev, slow.nsteps) == (same.nfev, same.nsteps)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-10)
    # the interpreted kernels call the plug-in's gamma* as Python: the compiled loop's steps to the last bit
    np.testing.assert_array_equal(fast.q, same.q)
    # Phi'' = -c Phi': Phi' decays like exp(-c t)
    exact = slow.phi_dot[0, 0] * np.exp(-8.0 * slow.t)
    np.testing.assert_allclose(slow.phi_dot[:, 0], exact, atol=1e-7)
    assert abs(slow.phi_dot[0, 0]) > 1e-3
