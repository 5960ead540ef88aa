"""What a user's MJCF file holds beside what the checks compare, in one record per model.

A file's contacts, joint and tendon limits and actuator force clamps act at some states only;
the checks run where none acts (crosscheck.checks.sampling.draws) and the trajectories stop
before the first one does (crosscheck.checks.trajectory.horizon). Its actuators push at a
stated control, and its initial state may have been projected onto the constraint manifold
(--project). None of that is a comparison, but each changes what the comparisons mean, so the
record `instantaneous` / `reference` / `model_file` (skipped: nothing is judged) says it, with
the figures as fields: contact_pairs, limits, states_rejected, controls, projection.
"""

from __future__ import annotations

from crosscheck.checks.records import Record, record
from crosscheck.checks.sampling import MAX_DRAWS_PER_STATE, Draws
from reference import models

QUANTITY = "model_file"
# what a rejected draw had acting, in words (crosscheck.checks.sampling.Draws.rejected)
REJECTED = {
    "contact": "in contact",
    "limit": "at a joint or tendon limit",
    "force limit": "with an actuator force at its clamp",
    "projection": "whose projection onto the constraints failed",
}


def _states(draws: Draws, present) -> str:
    """What the states are and how they were found."""
    n = len(draws.states)
    rejected = ", ".join(
        f"{count} {REJECTED.get(kind, kind)}" for kind, count in sorted(draws.rejected.items())
    )
    how = f"{draws.drawn} states drawn" + (f", rejected: {rejected}" if rejected else "")
    if not n:
        return (
            f"{present.summary()} present, and no consistent state where none acts was found "
            f"in {draws.drawn} draws ({MAX_DRAWS_PER_STATE} per state asked for; {how}): the "
            "instantaneous checks and the trajectories are not made"
        )
    text = (
        f"{present.summary()} present; none acts at the {n} checked states (MuJoCo's "
        f"collision detection finds no contact within the margins, every limited joint lies "
        f"strictly inside its range; {how})"
    )
    if draws.initial_acts:
        acting = "; ".join(map(str, draws.initial_acts[:3]))
        more = f" and {len(draws.initial_acts) - 3} more" if len(draws.initial_acts) > 3 else ""
        text += (
            f"; the initial state is not checked ({acting}{more}), and the trajectories start "
            "from checked state 0"
        )
    return text


def file_record(name: str, formulation: str, draws: Draws) -> Record | None:
    """The model_file record of a user's MJCF model.

    Parameters
    ----------
    name, formulation : str
        The registered model and the formulation its records are about.
    draws : crosscheck.checks.sampling.Draws
        Its checked states and how they were found.

    Returns
    -------
    Record or None
        Skipped (nothing is judged), with the figures as fields; None for a model that is not
        from an MJCF file.
    """
    from reference.mjcf.loader import MjcfImport  # MuJoCo loads only for a user's MJCF file

    src = models.user_source(name)
    if not isinstance(src, MjcfImport):
        return None
    details: dict = {}
    parts = [f"{models.origin(name)}"]
    if src.monitor is not None:
        found = src.monitor.present
        details |= {
            "contact_pairs": len(found.contact_pairs),
            "limits": found.limits,
            "states_rejected": dict(draws.rejected),
        }
        parts.append(_states(draws, found))
    else:
        parts.append("no contact pair, limit or force clamp")
    if src.actuation.controls:
        details["controls"] = dict(src.actuation.controls)
        listed = ", ".join(f"{k} = {v:g}" for k, v in src.actuation.controls.items())
        acting = len(src.actuation.joint)
        parts.append(
            f"actuators at their stated controls ({listed}); {acting} apply a force, a load "
            "on their joints (gain and bias at that control)"
        )
    if src.projection is not None:
        details["projection"] = dict(src.projection)
        p = src.projection
        parts.append(
            f"initial state projected onto the constraint manifold (--project): it violated "
            f"the constraints by {p['violation']:.3e}; qpos moved by "
            f"{p['position_change']:.3e}, qvel by {p['velocity_change']:.3e}"
        )
    return record(
        name,
        formulation,
        "reference",
        "instantaneous",
        QUANTITY,
        None,
        None,
        "; ".join(parts),
        **details,
    )
