"""Building blocks shared by the model declarations (bodies from positions, planar rotations)."""

from __future__ import annotations

import sympy as sp

from reference.system import Body, rate, rot_z, vec

T_SYM = sp.Symbol("t", real=True)


def particle(name: str, mass, r, coordinates, kinematics) -> Body:
    """A point mass at inertial position r(q, t); its velocity is dr/dt through q' = N(q, u)."""
    return Body(name, mass, v_G=rate(r, coordinates, kinematics, T_SYM), r_G=r)


def planar_body(name: str, mass, I_zz, r_G, angle, coordinates, kinematics) -> Body:
    """A rigid body moving in the XY plane and turning about Z by `angle` (a function of q).

    Its central inertia about Z is I_zz; the in-plane components play no part in planar motion
    and are left 0 here (the engines' models give the body a full inertia, see crosscheck).
    """
    return Body(
        name,
        mass,
        v_G=rate(r_G, coordinates, kinematics, T_SYM),
        inertia=sp.diag(0, 0, I_zz),
        omega=vec(0, 0, rate(angle, coordinates, kinematics, T_SYM)),
        r_G=r_G,
        R=rot_z(angle),
    )
