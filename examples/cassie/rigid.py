"""Cassie with its contacts and joint limits switched off and its actuators removed.

tests/data/cassie.xml is MuJoCo Menagerie's Cassie (the visual meshes left out). Its
collision geoms, joint ranges and motors act at some states only or need a control; until the
suite takes such files as they are, the reference and the engines are compared on this copy:
`<flag contact="disable" limit="disable"/>` in <option>, and the <actuator> and <sensor>
(which reads the actuators) sections removed. Bodies, joints (their damping, springs and
armature), the four loop-closing `connect`s and the keyframe are the file's.

    python examples/cassie/rigid.py > /tmp/cassie_rigid.xml
    crosscheck run --model-file /tmp/cassie_rigid.xml --instantaneous --out out/cassie
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[2] / "tests" / "data" / "cassie.xml"
OPTION = '<option timestep="0.0005"/>'
SWITCHED_OFF = (
    '<option timestep="0.0005">\n    <flag contact="disable" limit="disable"/>\n  </option>'
)


def rigid_copy(text: str) -> str:
    """The MJCF `text` of Cassie with contacts and limits disabled and no actuators."""
    if OPTION not in text:
        raise ValueError(f"expected Menagerie's {OPTION} in the file")
    text = text.replace(OPTION, SWITCHED_OFF)
    for section in ("actuator", "sensor"):
        text = re.sub(rf"\n  <{section}>.*?</{section}>\n", "\n", text, flags=re.S)
    return text


if __name__ == "__main__":
    sys.stdout.write(rigid_copy(SOURCE.read_text()))
