"""An MJCF file's actuators at a stated control: the force each applies, as a load on its joint.

MuJoCo's actuator force (mj_fwdActuation) is ``F = gain * input + bias`` on the actuator's
length L and velocity V, with

- ``input`` the control ``ctrl`` (clamped to ``ctrlrange`` where the actuator is
  ``ctrllimited``) for an actuator without activation dynamics, else its activation;
- ``gain = gainprm[0]`` (gaintype fixed) or ``gainprm[0] + gainprm[1] L + gainprm[2] V``
  (affine);
- ``bias = biasprm[0] + biasprm[1] L + biasprm[2] V`` (biastype affine; 0 for none);
- ``F`` clamped to ``forcerange`` where the actuator is ``forcelimited``;

and through a joint transmission on a hinge or slide, ``L = gear q`` (MuJoCo's qpos, the
joint's `ref` included), ``V = gear q'`` and the generalized force on the joint's dof is
``gear F``; through a fixed tendon, ``L = gear sum c_j q_j`` and ``c_j gear F`` on each of its
joints. So at a constant control a motor is a constant torque, a position servo
(``bias = (0, -kp, -kv)``) a spring with a damper pulling towards ``ctrl / gear``, and a velocity
servo (``bias = (0, 0, -kv)``) a damper. That force enters the reference as a load on each
joint's rate, as a damper does (reference.forces.joint_damper), and tests/test_actuators.py
holds it equal to mj_forward's ``qfrc_actuator``.

The control is stated: 0 by default, the keyframe's ``ctrl`` where the file has a keyframe,
or the value given for the actuator by name (``crosscheck run --ctrl NAME=VALUE``). Actuators
the reference cannot express are refused by name unless they apply no force at their control
(a transmission other than a hinge or slide joint or a fixed tendon, activation dynamics with
a nonzero control, gain or bias types other than fixed and affine). A force clamp
(``forcerange``, or the joint's ``actuatorfrcrange``) acts at some states only: it is
monitored like a joint limit (reference.mjcf.unilateral), not refused.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import mujoco
import numpy as np
import sympy as sp

from reference.errors import ModelFileError
from reference.forces import ForceElements
from reference.mjcf.checks import disabled, element
from reference.mjcf.exact import num
from reference.system import Force, vec

TRN = mujoco.mjtTrn
DYN = mujoco.mjtDyn
GAIN = mujoco.mjtGain
BIAS = mujoco.mjtBias
JNT = mujoco.mjtJoint
# activation dynamics that keep a zero activation at zero control (act' = ctrl, or
# (ctrl - act) / tau): at control 0 from activation 0 the input stays 0
AFFINE_GAIN, AFFINE_BIAS = int(GAIN.mjGAIN_AFFINE), int(BIAS.mjBIAS_AFFINE)
ZERO_PRESERVING = (int(DYN.mjDYN_INTEGRATOR), int(DYN.mjDYN_FILTER), int(DYN.mjDYN_FILTEREXACT))


def actuator_name(m, a: int) -> str:
    """The actuator's name in the file, or #index where it has none."""
    return element(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)


@dataclass(frozen=True)
class LinearActuator:
    """One actuator whose length is linear in hinge and slide coordinates (a joint, or a fixed
    tendon): L = sum k_j q_j, V = sum k_j w_j, and k_j F on dof j (k_j: gear times the
    tendon's coefficient)."""

    name: str
    terms: tuple[tuple[int, int, float], ...]  # (dof, qpos address, k) of each joint
    input: float  # the control, or the activation (0) of an actuator with dynamics
    gain: tuple[float, float, float]  # gain = g0 + g1 L + g2 V
    bias: tuple[float, float, float]  # bias = b0 + b1 L + b2 V
    forcerange: tuple[float, float] | None  # the clamp, where forcelimited

    def force(self, qpos, qvel):
        """The unclamped actuator force F at a state (qpos, qvel indexable by address)."""
        L = sum(k * qpos[adr] for _dof, adr, k in self.terms)
        V = sum(k * qvel[dof] for dof, _adr, k in self.terms)
        g0, g1, g2 = self.gain
        b0, b1, b2 = self.bias
        return (g0 + g1 * L + g2 * V) * self.input + b0 + b1 * L + b2 * V


@dataclass(frozen=True)
class Actuation:
    """The actuators of a file at their stated controls.

    Parameters
    ----------
    controls : dict
        Every actuator's control, by name (the ones that apply no force included).
    joint : tuple of LinearActuator
        The actuators that can apply a force, each on its joint or fixed tendon's joints.
    notes : tuple of str
        Actuators left out because they apply no force at their control.
    """

    controls: dict[str, float] = field(default_factory=dict)
    joint: tuple[LinearActuator, ...] = ()
    notes: tuple[str, ...] = ()

    def qfrc(self, qpos, qvel, nv: int) -> np.ndarray:
        """MuJoCo's qfrc_actuator at a state where no force clamp acts (numbers)."""
        out = np.zeros(nv)
        for a in self.joint:
            F = a.force(qpos, qvel)
            for dof, _adr, k in a.terms:
                out[dof] += k * F
        return out

    def loads(self, rates_by_dof: Mapping[int, sp.Expr], coords_by_qpos) -> ForceElements:
        """The actuators as loads on the joints' rates: on each joint, a Force along the
        one-component velocity w (as reference.forces.joint_damper writes a damper),
        generalized force k F(L, V) dw/du, power k F w; L and V in the reference's
        coordinates and rates, every number exact."""
        loads = []
        for a in self.joint:
            q = {adr: coords_by_qpos[adr] for _dof, adr, _k in a.terms}
            w = {dof: rates_by_dof[dof] for dof, _adr, _k in a.terms}
            exact = LinearActuator(
                a.name,
                tuple((dof, adr, num(k)) for dof, adr, k in a.terms),
                num(a.input),
                tuple(num(x) for x in a.gain),  # type: ignore[arg-type]
                tuple(num(x) for x in a.bias),  # type: ignore[arg-type]
                a.forcerange,
            )
            F = sp.expand(exact.force(q, w))
            for dof, _adr, k in exact.terms:
                loads.append(
                    Force(
                        f"actuator:{a.name}:{dof}",
                        velocity=vec(w[dof], 0, 0),
                        force=vec(sp.expand(k * F), 0, 0),
                    )
                )
        return ForceElements(loads=tuple(loads))


def stated_controls(m, given: Mapping[str, float] | None = None) -> dict[str, float]:
    """Every actuator's control: ``given`` by name, else keyframe 0's ctrl, else 0.

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled file.
    given : mapping of str to float, optional
        Controls by actuator name (--ctrl).

    Returns
    -------
    dict
        Actuator name -> control, every actuator of the file.

    Raises
    ------
    ModelFileError
        A name in ``given`` that is not an actuator of the file, or a control outside a
        limited actuator's ctrlrange (MuJoCo would clamp it: the stated value would not be the
        one applied).
    """
    names = [actuator_name(m, a) for a in range(m.nu)]
    given = dict(given or {})
    unknown = sorted(set(given) - set(names))
    if unknown:
        listed = ", ".join(names) if names else "none"
        raise ModelFileError(
            f"--ctrl {', '.join(unknown)}: no such actuator in the file (its actuators: {listed})"
        )
    base = np.array(m.key_ctrl[0], float) if m.nkey and m.nu else np.zeros(m.nu)
    out = {}
    clamp = not disabled(m, "mjDSBL_CLAMPCTRL")
    for a, name in enumerate(names):
        value = float(given.get(name, base[a]))
        lo, hi = (float(x) for x in m.actuator_ctrlrange[a])
        if clamp and m.actuator_ctrllimited[a] and not lo <= value <= hi:
            where = "--ctrl" if name in given else "keyframe 0's ctrl"
            raise ModelFileError(
                f"actuator '{name}': the control {value:g} ({where}) is outside its ctrlrange "
                f"[{lo:g}, {hi:g}], where MuJoCo clamps it; give a control inside the range"
            )
        out[name] = value
    return out


def _applies_force(m, a: int, value: float) -> bool:
    """Whether the actuator can apply a nonzero force at this input (gain times a nonzero
    input, or a nonzero bias)."""
    bias = int(m.actuator_biastype[a]) != int(BIAS.mjBIAS_NONE) and np.any(
        m.actuator_biasprm[a, :3]
    )
    return bool(bias or (value != 0.0 and np.any(m.actuator_gainprm[a, :3])))


def _problem(m, a: int, value: float, act0: float) -> str | None:
    """Why the reference cannot express the actuator at its control (None: it can, or it
    applies no force there)."""
    dyn, gain, bias = (
        int(m.actuator_dyntype[a]),
        int(m.actuator_gaintype[a]),
        int(m.actuator_biastype[a]),
    )
    if bias not in (int(BIAS.mjBIAS_NONE), int(BIAS.mjBIAS_AFFINE)):
        return f"a {BIAS(bias).name.removeprefix('mjBIAS_').lower()} bias force"
    if dyn != int(DYN.mjDYN_NONE):
        if dyn not in ZERO_PRESERVING:
            return f"{DYN(dyn).name.removeprefix('mjDYN_').lower()} activation dynamics"
        if value != 0.0 or act0 != 0.0:
            return "an activation state driven by a nonzero control"
    elif value != 0.0 and gain not in (int(GAIN.mjGAIN_FIXED), int(GAIN.mjGAIN_AFFINE)):
        return f"a {GAIN(gain).name.removeprefix('mjGAIN_').lower()} gain"
    if _terms(m, a) is None:
        trn = int(m.actuator_trntype[a])
        kind = TRN(trn).name.removeprefix("mjTRN_").lower()
        if trn in (int(TRN.mjTRN_JOINT), int(TRN.mjTRN_JOINTINPARENT)):
            return "a transmission on a ball or free joint"
        return f"a {kind} transmission" + (" (a spatial tendon)" if kind == "tendon" else "")
    return None


def _affine(prm, kind: int, affine: int, gain: bool) -> tuple[float, float, float]:
    """(p0, p1, p2) of an affine gain or bias; a fixed gain (or any gain, which multiplies a
    zero input) is (p0, 0, 0), a bias of type none (0, 0, 0)."""
    if kind == affine:
        return (float(prm[0]), float(prm[1]), float(prm[2]))
    return (float(prm[0]), 0.0, 0.0) if gain else (0.0, 0.0, 0.0)


def _terms(m, a: int) -> tuple[tuple[int, int, float], ...] | None:
    """(dof, qpos address, k) of an actuator whose length is linear in hinge and slide
    coordinates: a joint transmission (k = gear) or a fixed tendon's (k = gear times each
    coefficient); None for any other transmission."""
    trn, i = int(m.actuator_trntype[a]), int(m.actuator_trnid[a, 0])
    gear = float(m.actuator_gear[a, 0])
    hinge_slide = (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE))
    if trn in (int(TRN.mjTRN_JOINT), int(TRN.mjTRN_JOINTINPARENT)):
        if int(m.jnt_type[i]) not in hinge_slide:
            return None
        return ((int(m.jnt_dofadr[i]), int(m.jnt_qposadr[i]), gear),)
    if trn != int(TRN.mjTRN_TENDON):
        return None
    adr, num_ = int(m.tendon_adr[i]), int(m.tendon_num[i])
    terms = []
    for w in range(adr, adr + num_):
        j = int(m.wrap_objid[w])
        if int(m.wrap_type[w]) != int(mujoco.mjtWrap.mjWRAP_JOINT):
            return None  # a spatial tendon: its length is a path through sites
        terms.append((int(m.jnt_dofadr[j]), int(m.jnt_qposadr[j]), gear * float(m.wrap_prm[w])))
    return tuple(terms)


def actuation(m, controls: Mapping[str, float]) -> tuple[Actuation, list[tuple[str, str]]]:
    """The actuators at their controls.

    Parameters
    ----------
    m : mujoco.MjModel
        The compiled file.
    controls : mapping of str to float
        Every actuator's control (stated_controls).

    Returns
    -------
    Actuation
        The actuators that apply a force, as loads, and notes on those left out.
    list of (str, str)
        The actuators the reference cannot express, (name, why); empty when actuation is
        disabled.
    """
    if m.nu == 0 or disabled(m, "mjDSBL_ACTUATION"):
        note = () if m.nu == 0 else ("actuation is disabled: the actuators apply no force",)
        return Actuation(dict(controls), (), note), []
    act0 = np.array(m.key_act[0], float) if m.nkey and m.na else np.zeros(m.na)
    joint, notes, problems = [], [], []
    for a in range(m.nu):
        name = actuator_name(m, a)
        value = float(controls[name])
        if m.opt.disableactuator & (1 << int(m.actuator_group[a])):
            notes.append(f"actuator '{name}' is in a disabled group: no force")
            continue
        adr = int(m.actuator_actadr[a])
        a0 = float(act0[adr]) if adr >= 0 else 0.0
        if not _applies_force(m, a, value if adr < 0 else a0):
            notes.append(f"actuator '{name}' applies no force at its control {value:g}")
            continue
        why = _problem(m, a, value, a0)
        if why is not None:
            problems.append((name, why))
            continue
        limited = bool(m.actuator_forcelimited[a])
        joint.append(
            LinearActuator(
                name,
                _terms(m, a),  # type: ignore[arg-type]
                value if adr < 0 else 0.0,
                _affine(m.actuator_gainprm[a], int(m.actuator_gaintype[a]), AFFINE_GAIN, True),
                _affine(m.actuator_biasprm[a], int(m.actuator_biastype[a]), AFFINE_BIAS, False),
                tuple(float(x) for x in m.actuator_forcerange[a]) if limited else None,  # type: ignore[arg-type]
            )
        )
    return Actuation(dict(controls), tuple(joint), tuple(notes)), problems
