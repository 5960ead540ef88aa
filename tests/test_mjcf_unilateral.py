"""Contacts, joint and tendon limits and actuator force clamps of users' MJCF files: present,
monitored, never active at the checked states, the trajectories cut before they act, and
refused only where one acts at every consistent state. Real MuJoCo, no mocks.

Files: tests/data/robot_arm.xml (this project's: a floor and capsules with contacts on, three
limited joints, a limited fixed tendon, a clamped actuator force), and real ones with their
provenance in their headers: tests/data/real/mujoco_dofless_weld.xml (two welded bodies whose
geoms overlap), mujoco_sleep_equality.xml (free boxes that fall onto a floor),
mujoco_equality_site.xml (fluid forces), pinocchio_cassie.xml (49 contact pairs, 16 limits).
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck.checks.sampling import draws, monitor_of
from crosscheck.cli import main
from crosscheck.user_models import load_all, register_all
from reference import models
from reference.errors import UnsupportedModelError
from reference.mjcf.loader import import_mjcf
from reference.mjcf.unilateral import contact_pairs
from reference.numeric.model import NumericModel

DATA = Path(__file__).with_name("data")
REAL = DATA / "real"
ARM = DATA / "robot_arm.xml"


def registered(path: Path, **loading) -> NumericModel:
    """The file's model registered as `crosscheck run` registers it, derived."""
    (um,) = load_all([path], entry_points=False, **loading)
    register_all([um])
    return NumericModel(models.get(um.name))


def kinds(monitor, q, u=None) -> set[str]:
    u = np.zeros(len(q)) if u is None else u
    return {a.kind for a in monitor.active(np.asarray(q, float), np.asarray(u, float))}


def test_robot_arm_holds_every_kind_and_the_monitor_names_each():
    """7 contact pairs, 3 joint limits, 1 tendon limit, 1 force clamp; each acts exactly where
    it should: the upper arm turned down into the base (contact), the shoulder past its range,
    the fixed tendon past its range, the tendon actuator's force past its clamp."""
    imp = import_mjcf(ARM)
    mon = imp.monitor
    found = mon.present
    assert (len(found.contact_pairs), len(found.joint_limits)) == (7, 3)
    assert (found.tendon_limits, found.force_limits) == (
        ("coupling",),
        ("actuator 'tendon_drive'",),
    )
    assert found.summary() == (
        "7 contact pairs, 3 joint limits, 1 tendon limit, 1 actuator force clamp"
    )
    rest = np.array([0.3, 0.5, 0.0])  # keyframe 0: clear of everything
    assert kinds(mon, rest) == set()
    assert kinds(mon, [np.pi / 2, 0.2, 0.0]) == {"contact"}  # the upper arm inside the base
    assert kinds(mon, [np.radians(-100), 0.5, 0.0]) == {"limit"}  # the shoulder on its bound
    assert kinds(mon, [-1.6, -2.0, 0.0]) == {"limit"}  # coupling = -1.6 - 2.0/2 < -2.5
    named = [str(a) for a in mon.active([-1.6, -2.0, 0.0], [0, 0, 0])]
    assert named == ["tendon 'coupling' at its limit"]
    # the clamp acts on F = 0.3 + 0.05 L + 0.1 - L - 0.2 V at V = -30: 6.4 > 5
    assert kinds(mon, [0.0, 0.0, 0.0], [-30.0, 0.0, 0.0]) == {"force limit"}


@pytest.mark.parametrize("flags", ["", '<option><flag filterparent="disable"/></option>'])
def test_contact_pairs_are_the_ones_mujoco_collides(flags):
    """Every geom overlaps every other, so MuJoCo's contacts are exactly the pairs its broad
    phase keeps: contype/conaffinity, same weld body, parent filter, <exclude>."""
    xml = f"""<mujoco>{flags}<worldbody><geom name="w" size="1"/>
      <body name="a"><joint/><geom name="ga" size="1"/>
        <body name="b"><joint/><geom name="gb" size="1"/>
          <body name="c"><joint/><geom name="gc" size="1"/></body>
          <body name="f"><geom name="gf" size="1"/></body></body></body>
      <body name="d"><joint type="slide"/><geom name="gd" size="1" contype="2" conaffinity="2"/>
        <geom name="gd2" size="1" contype="1" conaffinity="0"/></body>
      <body name="e"><freejoint/><geom name="ge" size="1"/></body>
    </worldbody><contact><exclude body1="c" body2="e"/></contact></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    collided = set()
    for c in d.contact[: d.ncon]:
        g1, g2 = sorted((c.geom1, c.geom2))
        collided.add(f"geom '{m.geom(g1).name}' / geom '{m.geom(g2).name}'")
    assert collided and set(contact_pairs(m)) == collided


def test_a_contact_acting_at_every_consistent_state_is_refused():
    """MuJoCo's dofless_weld.xml: two free bodies welded with their spheres overlapping touch
    at every consistent state: one line naming the pair, the bodies and the way out."""
    with pytest.raises(UnsupportedModelError) as err:
        import_mjcf(REAL / "mujoco_dofless_weld.xml")
    message = str(err.value)
    assert "\n" not in message
    assert "geom '#0' / geom '#1' touch at the initial state on bodies '1' and '2'" in message
    assert "acts at every consistent state" in message
    assert '<exclude body1="1" body2="2"/>' in message


def test_refusals_group_repeated_problems_in_one_line(tmp_path):
    """Seven joints with dry friction and fluid forces: one line, the joints grouped ('7 joints
    have dry friction (frictionloss): j0, ..., j4 and 2 more: set it to 0'); a real file with
    fluid forces (MuJoCo's equality_site.xml) is refused for them."""
    chain = (
        "".join(
            f'<body pos="0 0 -0.1"><joint name="j{k}" axis="0 1 0" frictionloss="0.1"/>'
            '<geom size="0.05" contype="0" conaffinity="0"/>'
            for k in range(7)
        )
        + "</body>" * 7
    )
    path = tmp_path / "rough.xml"
    path.write_text(f'<mujoco><option density="1.2"/><worldbody>{chain}</worldbody></mujoco>')
    with pytest.raises(UnsupportedModelError) as err:
        import_mjcf(path)
    message = str(err.value)
    assert "\n" not in message and len(message) < 300
    assert (
        "7 joints have dry friction (frictionloss): j0, j1, j2, j3, j4 and 2 more: set it to 0"
        in message
    )
    assert "fluid forces" in message
    with pytest.raises(UnsupportedModelError, match="fluid forces"):
        import_mjcf(REAL / "mujoco_equality_site.xml")


def test_cassie_is_accepted_with_its_contacts_and_limits_monitored():
    """Pinocchio's closed-chain Cassie (32 dof, 4 connects, a free base): its 49 contact pairs
    and 16 joint limits are no longer a 2,500-character refusal; at qpos0 its feet's crank and
    foot joints sit outside their ranges (MuJoCo's own limit rows say so), so that state is
    left out of the checks."""
    imp = import_mjcf(REAL / "pinocchio_cassie.xml")
    assert imp.monitor.present.summary() == "49 contact pairs, 16 joint limits"
    at_rest = [str(a) for a in imp.monitor.active(imp.model.initial_q, imp.model.initial_u)]
    assert at_rest == [
        f"joint '{side}-{j}' at its limit"
        for side in ("left", "right")
        for j in ("foot-crank", "foot")
    ]


def test_sampler_draws_inside_the_ranges_and_rejects_contacts():
    """robot_arm's checked states: none with anything acting, every limited coordinate strictly
    inside its range, the rejected draws counted by what acted."""
    nm = registered(ARM)
    drawn = draws(nm, 6)
    mon = monitor_of(nm.model)
    assert len(drawn.states) == 6 and drawn.initial_acts == []
    for q, u in drawn.states:
        assert mon.active(q, u) == []
        for _j, adr, lo, hi, _margin in mon.ranges:
            assert lo < q[adr] < hi
    assert drawn.rejected == {"contact": 4, "limit": 1}
    assert drawn.drawn == 5 + sum(drawn.rejected.values())


def _always_touching(tmp_path) -> Path:
    """A hinged wheel whose rim always overlaps a static block (it turns about its own
    centre): never rigid, never free of the contact."""
    path = tmp_path / "rubbing.xml"
    path.write_text("""<mujoco model="rubbing"><worldbody>
      <geom name="block" type="box" size="0.2 0.2 0.2" pos="0.55 0 0"/>
      <body name="wheel"><joint name="axle" axis="0 1 0"/>
        <geom name="rim" type="cylinder" size="0.5 0.05" euler="90 0 0"/></body>
      </worldbody></mujoco>""")
    return path


def test_no_state_without_contact_is_one_record(tmp_path):
    """Where every draw is in contact the run writes one record saying so (with the draws and
    why they were rejected) and makes no comparison."""
    from crosscheck.run.checks import run

    nm = registered(_always_touching(tmp_path))
    records, series = run([nm.model.name], ["mujoco", "pinocchio"], 3, t_end=1.0)
    assert series == [] and len(records) == 1
    (rec,) = records
    assert (rec["quantity"], rec["skipped"], rec["contact_pairs"]) == ("model_file", True, 1)
    assert rec["states_rejected"] == {"contact": 150}
    assert "no consistent state where none acts was found in 150 draws" in rec["reason"]


def test_trajectories_end_before_the_first_limit():
    """robot_arm's wrist motor drives the wrist to its stop at 0.108 s: the trajectories are
    compared on [0, 0.106] s, and the horizon record names the joint and the time; every
    engine's records pass on that window."""
    from crosscheck.checks.trajectory.check import trajectory_records
    from crosscheck.engines.registry import get_engine

    nm = registered(ARM)
    engines = [get_engine("mujoco"), get_engine("pinocchio")]
    records, _ = trajectory_records(nm.model.name, nm, engines, 1.0)
    (horizon,) = [r for r in records if r["quantity"] == "horizon"]
    assert horizon["t_end"] == 0.106 and horizon["t_requested"] == 1.0
    assert (
        "at t = 0.108 s the reference's motion reaches joint 'wrist' at its limit"
        in horizon["reason"]
    )
    judged = [r for r in records if not r["skipped"]]
    assert {r["engine"] for r in judged} == {"reference", "mujoco", "pinocchio"}
    assert all(r["passed"] and r["t_end"] == 0.106 for r in judged)


@pytest.mark.slow  # a real file's whole run with trajectories: about 5 s warm
def test_falling_boxes_are_compared_until_they_touch_the_floor(tmp_path):
    """MuJoCo's sleep/equality.xml: free boxes above a floor (33 contact pairs) fall onto it
    at t = 0.27 s; the trajectories stop at 0.267 s with the pair named."""
    code = main(
        ["run", "--model-file", str(REAL / "mujoco_sleep_equality.xml"), "--engines",
         "pinocchio", "--states", "2", "--t-end", "1", "--no-report", "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    records = json.loads((tmp_path / "results.json").read_text())["records"]
    (horizon,) = [r for r in records if r["quantity"] == "horizon"]
    assert horizon["t_end"] == 0.267
    assert "geom '#0' / geom '#4' in contact" in horizon["reason"]


def test_an_initial_state_in_contact_is_replaced_by_a_checked_one(tmp_path):
    """A pendulum resting against a block at qpos0: that state is left out (the record says
    what acts there), and the trajectories start from checked state 0."""
    from crosscheck.checks.trajectory.check import trajectory_records
    from crosscheck.checks.user_file import file_record
    from crosscheck.engines.registry import get_engine

    path = tmp_path / "resting.xml"
    path.write_text("""<mujoco model="resting"><worldbody>
      <geom name="block" type="box" size="0.1 0.1 0.1" pos="0 0 -0.69"/>
      <body name="rod"><joint name="pivot" axis="0 1 0"/>
        <geom name="bob" type="sphere" size="0.1" pos="0 0 -0.5"/></body>
      </worldbody></mujoco>""")
    nm = registered(path)
    drawn = draws(nm, 3)
    assert [str(a) for a in drawn.initial_acts] == [
        "geom 'bob' / geom 'block' in contact (distance -0.01 m)"
    ]
    rec = file_record(nm.model.name, nm.formulation, drawn)
    assert (
        "the initial state is not checked (geom 'bob' / geom 'block' in contact" in (rec["reason"])
    )
    start = drawn.states[0]
    records, _ = trajectory_records(nm.model.name, nm, [get_engine("pinocchio")], 0.2, start=start)
    judged = [r for r in records if not r["skipped"]]
    assert judged and all(r["passed"] for r in judged)


@pytest.mark.slow  # three files derived and run through the CLI: about 12 s warm
def test_user_file_records_follow_the_schema(tmp_path):
    """The model_file record's fields (contact pairs, limits, rejected draws, controls, the
    projection) and the left-out rows of a file with quaternions, written by one run, follow
    the results.json schema."""
    from crosscheck.report.inputs import schema_violations
    from crosscheck.schema import results_schema

    files = [ARM, DATA / "free_weld.xml", DATA / "loop_keyframe.xml"]
    code = main(
        ["run", *[a for f in files for a in ("--model-file", str(f))], "--project",
         "--engines", "mujoco,pinocchio", "--states", "2", "--instantaneous", "--no-report",
         "--out", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    data = json.loads((tmp_path / "results.json").read_text())
    assert schema_violations(data) == []
    new = {"contact_pairs", "limits", "states_rejected", "controls", "projection", "rows_left_out"}
    written = {k for r in data["records"] for k in r}
    assert new <= written <= set(results_schema()["$defs"]["record"]["properties"])


def test_the_search_for_a_limit_stops_at_the_window_that_finds_it(monkeypatch):
    """robot_arm reaches its wrist stop at 0.108 s of a 5 s horizon: the reference runs that
    look for it cover windows doubling from 16 ms, up to the one that holds 0.108 s, and never
    the rest of the horizon (a robot starting against a limit costs milliseconds)."""
    import reference.integrate.driver as driver
    from crosscheck.checks.trajectory.horizon import FIRST_WINDOW, first_activation

    nm = registered(ARM)
    spans, real = [], driver.simulate

    def spy(nm_, q0, u0, t_end, *args, **kw):
        spans.append((kw.get("t0", 0.0), t_end))
        return real(nm_, q0, u0, t_end, *args, **kw)

    monkeypatch.setattr(driver, "simulate", spy)
    q0, u0 = nm.project(nm.model.initial_q, nm.model.initial_u)
    t_act, what = first_activation(nm, q0, u0, 5.0, monitor_of(nm.model).active, 1e-10)
    assert t_act == pytest.approx(0.108) and "wrist" in what
    ends = [round(t1, 9) for _t0, t1 in spans]
    assert ends == [0.016, 0.048, 0.112] and FIRST_WINDOW == 16
    assert all(round(t0, 9) == e for (t0, _), e in zip(spans[1:], ends, strict=False))
