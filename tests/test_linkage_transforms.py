"""Joint transforms and cut-joint equations of each joint type, against the brief's formulas
and hand derivations (numbers, not the code's own output)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from csim.linkage.constraints import cut_joint_equations
from csim.linkage.frames import Frames
from csim.linkage.tables import Coupling
from csim.linkage.transforms import euler_zxz, frame_transform, inverse, joint_transform, link_to_link

RNG = np.random.default_rng(7)


def numeric(M):
    return np.array(M.evalf(), dtype=float)


def Rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def Rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def hom(A=None, r=(0, 0, 0)):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.eye(3) if A is None else A, r
    return T


@pytest.mark.parametrize("kind", ["R", "P", "C", "U", "S"])
def test_joint_transform_matches_the_brief(kind):
    q = RNG.uniform(-np.pi, np.pi, 3)
    c1, s1, c2, s2, c3, s3 = np.cos(q[0]), np.sin(q[0]), np.cos(q[1]), np.sin(q[1]), np.cos(q[2]), np.sin(q[2])
    expected = {
        "R": hom(Rz(q[0])),
        "P": hom(r=(0, 0, q[0])),
        "C": hom(Rz(q[0]), (0, 0, q[1])),
        # the brief's matrix, written out
        "U": hom(np.array([[c1 * c2, -c1 * s2, -s1], [s1 * c2, -s1 * s2, c1], [-s2, -c2, 0]])),
        # z-x'-z'' Euler matrix, written out (the paper's eq. 7)
        "S": hom(np.array([[c1 * c3 - s1 * c2 * s3, -c1 * s3 - s1 * c2 * c3, s1 * s2],
                           [s1 * c3 + c1 * c2 * s3, -s1 * s3 + c1 * c2 * c3, -c1 * s2],
                           [s2 * s3, s2 * c3, c2]])),
    }[kind]
    n = {"R": 1, "P": 1, "C": 2, "U": 2, "S": 3}[kind]
    got = numeric(joint_transform(kind, [sp.Float(x) for x in q[:n]]))
    assert np.allclose(got, expected, atol=1e-14)


def test_frame_transform_and_link_to_link():
    p = RNG.uniform(-1, 1, 6)
    T = numeric(frame_transform([sp.Float(x) for x in p]))
    assert np.allclose(T, hom(Rz(p[3]) @ Rx(p[4]) @ Rz(p[5]), p[:3]), atol=1e-14)
    assert np.allclose(numeric(euler_zxz(sp.pi / 2, sp.pi / 2, 0))[:3, 2], [1, 0, 0])  # z onto global x
    A = frame_transform([sp.Float(x) for x in RNG.uniform(-1, 1, 6)])
    B = frame_transform([sp.Float(x) for x in RNG.uniform(-1, 1, 6)])
    J = joint_transform("R", [sp.Float(0.3)])
    assert np.allclose(numeric(link_to_link(A, J, B)), numeric(A) @ hom(Rz(0.3)) @ np.linalg.inv(numeric(B)))
    assert np.allclose(numeric(inverse(A)), np.linalg.inv(numeric(A)))


def random_frame():
    a = RNG.uniform(-np.pi, np.pi, 3)
    return hom(Rz(a[0]) @ Rx(a[1]) @ Rz(a[2]), RNG.uniform(-1, 1, 3))


@pytest.mark.parametrize("kind", ["R", "P", "C", "U", "S"])
def test_cut_joint_equations_match_a_hand_derivation(kind):
    """Frames ik and jm at random poses; equations in the documented order."""
    Tik, Tjm = random_frame(), random_frame()
    frames = Frames(local={(1, 1): sp.eye(4), (2, 1): sp.eye(4)}, joints={}, relative={},
                    links={1: sp.Matrix(Tik), 2: sp.Matrix(Tjm)})
    coupling = Coupling(1, None, 1, 1, 2, 1, kind, "test")
    got = [float(e.expression) for e in cut_joint_equations(coupling, frames)]
    x, y, z = Tik[:3, 0], Tik[:3, 1], Tik[:3, 2]
    d = Tjm[:3, 3] - Tik[:3, 3]
    yj, zj = Tjm[:3, 1], Tjm[:3, 2]
    expected = {
        "R": [*d, y @ zj, x @ zj],                       # r_ik = r_jm; z_ik = z_jm (2 of 3)
        "P": [x @ d, y @ d, y @ zj, x @ zj, x @ yj],     # in-plane offset; A_ik = A_jm (3 of 9)
        "C": [x @ d, y @ d, y @ zj, x @ zj],
        "U": [*d, z @ zj],                               # r_ik = r_jm; z_ik . z_jm = 0
        "S": [*d],
    }[kind]
    assert np.allclose(got, expected, atol=1e-13)


@pytest.mark.parametrize("kind,count", [("R", 5), ("P", 5), ("C", 4), ("U", 4), ("S", 3)])
def test_cut_joint_equations_vanish_when_the_joint_is_closed(kind, count):
    """Frame jm = frame ik moved by the joint's own transform: every equation holds."""
    Tik = random_frame()
    n = {"R": 1, "P": 1, "C": 2, "U": 2, "S": 3}[kind]
    Tjm = Tik @ numeric(joint_transform(kind, [sp.Float(v) for v in RNG.uniform(-1, 1, n)]))
    frames = Frames(local={(1, 1): sp.eye(4), (2, 1): sp.eye(4)}, joints={}, relative={},
                    links={1: sp.Matrix(Tik), 2: sp.Matrix(Tjm)})
    eqs = cut_joint_equations(Coupling(1, None, 1, 1, 2, 1, kind, "test"), frames)
    assert len(eqs) == count
    assert max(abs(float(e.expression)) for e in eqs) < 1e-13
