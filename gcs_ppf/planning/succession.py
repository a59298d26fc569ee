"""A new leader when the leader is lost: the wingman of highest priority leads, and every
slot is moved so that each vehicle keeps its place in the formation.

Pure.  Slots are offsets in the leader's flight-path frame (Eq. 6): wingman w flies at
``slot_w`` from the leader.  With the wingman n leading, the formation's frame is the
same (its flight-path axes, the formation flying on as before), so each vehicle keeps its
offset from the formation's reference — where the lost leader was — exactly: w's slot is
``slot_w − slot_n``, and the lost leader's, should it come back, ``−slot_n`` (it rejoins
as a wingman where it flew).  The geometry allows this whole: no slot is dropped, none
merged; only the reference moves to the new leader.
"""

from __future__ import annotations

from gcs_ppf.mission import Mission, Vehicle
from gcs_ppf.planning.scene import priority_key


def successors(mission: Mission, lost: set[int]) -> list[Vehicle]:
    """The wingmen that may lead when the leader is lost, first the one that does: by
    avoidance priority (``priority``, then id), those not ``lost``."""
    return sorted((w for w in mission.wingmen if w.id not in lost), key=priority_key)


def succeed(mission: Mission, lost: set[int]) -> Mission | None:
    """``mission`` led by the first of ``successors`` (its leader a wingman at the offset it
    flew at, every slot moved to the new leader), or None when no wingman is left to lead.
    Every distance between two places is kept, so a valid mission stays one."""
    heirs = successors(mission, lost)
    return led_by(mission, heirs[0]) if heirs else None


def led_by(mission: Mission, heir: Vehicle) -> Mission:
    """``mission`` with ``heir`` leading and the slots moved to it (validated again)."""
    assert heir.slot is not None, "a wingman has a slot"
    hx, hy, hz = heir.slot
    doc = mission.model_dump()
    for v in doc["vehicles"]:
        if v["id"] == heir.id:
            v.update(role="leader", slot=None)
            continue
        sx, sy, sz = (0.0, 0.0, 0.0) if v["slot"] is None else v["slot"]
        v.update(role="wingman", slot=(sx - hx, sy - hy, sz - hz))
    return Mission.model_validate(doc)
