"""The numeric model's functions (csim.model.numeric): NaN, never an exception, outside math's domain."""
from __future__ import annotations

import math

import numpy as np

from csim.model.numeric import _nan_outside_domain


def test_domain_errors_become_nan_of_the_right_shape(qr_model, qr_par):
    q = np.array([np.inf, 0.0, 0.0])
    phi = qr_model.phi(q, qr_par)  # math.cos(inf) inside: "math domain error" before
    assert phi.shape == (qr_model.n_constraints,) and np.isnan(phi).all()
    assert np.isnan(qr_model.potential_energy(np.array([np.nan, 0.0, 0.0]), qr_par))
    assert qr_model.phi_q(q, qr_par).shape == (qr_model.n_constraints, 3)


def test_the_guard_keeps_values_and_shapes():
    def f(q, par):
        return np.array([[math.sqrt(q[0]), 1.0], [2.0, 3.0]])

    g = _nan_outside_domain(f)
    assert g(np.array([4.0]), np.zeros(0))[0, 0] == 2.0
    out = g(np.array([-1.0]), np.zeros(0))
    assert out.shape == (2, 2) and np.isnan(out).all()


def test_the_models_bytecode_is_read_back_and_a_damaged_file_compiled_again(tmp_path, monkeypatch):
    import pytest

    from csim.mechanisms import get_mechanism
    from csim.model import cache
    from csim.model.numeric import build_numeric_model

    monkeypatch.setenv("CSIM_CACHE_DIR", str(tmp_path))
    definition = get_mechanism("pendulum")
    q, par = np.array([0.3, -0.9]), np.array([p.default for p in definition.parameters])
    first = build_numeric_model(definition)
    [code] = tmp_path.glob("*.code")
    with monkeypatch.context() as patch:  # read back, not compiled
        patch.setattr(cache, "compile", lambda *args: pytest.fail("compiled again"), raising=False)
        again = build_numeric_model(definition)
    code.write_bytes(b"\x00 not marshal data")
    mended = build_numeric_model(definition)
    for model in (again, mended):
        assert np.array_equal(model.mass(q, par), first.mass(q, par))
    assert cache.marshal.loads(code.read_bytes()).co_filename == f"<csim model {definition.name}>"
