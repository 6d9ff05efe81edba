"""The contact tiers' verdict on a settled pose: MuJoCo's own spread first, then the tolerance."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from conformance import tolerances as tolerance_file
from conformance.divergence import Divergence
from conformance.report import metric
from conformance.tiers.rollouts import UNTOUCHED, settled_verdict

TOLERANCES = tolerance_file.load()
BAND = TOLERANCES["contact.final_pose_band"]
SHARE = TOLERANCES.setting("contact", "spread_fraction") * BAND  # MuJoCo's spread from which nothing is predictable


def _metrics(deviation: float) -> list:
    return [metric("final_pose_band", [deviation], BAND, "m"), metric("rest_height", [0.0], 1.0, "m")]


@pytest.mark.parametrize(
    "deviation,spread,status",
    [
        (2.0 * BAND, SHARE, "chaotic"),  # MuJoCo's spread at the share: chaotic whatever ours
        (0.5 * BAND, SHARE, "chaotic"),
        (2.0 * BAND, 0.99 * SHARE, "fail"),  # just below it, a deviation past the band fails
        (0.99 * BAND, 0.99 * SHARE, "pass"),
        (1.01 * BAND, 0.0, "fail"),
    ],
)
def test_a_settled_verdict_is_chaotic_by_mujocos_spread_and_fails_only_beyond_it(deviation, spread, status):
    found, notes = settled_verdict(_metrics(deviation), np.array([0.0, spread]), BAND, TOLERANCES, None)
    assert found == status
    if status == "chaotic":
        said = (
            f"MuJoCo's own settled pose moves {spread:.3g} m under a 0.001 perturbation of the start, at least "
            f"0.5 of the {BAND:g} m band: chaotic whatever SAPIEN's deviation ({deviation:.3g} m)"
        )
        assert notes == [said]
    elif status == "fail":  # a failure exceeds the tolerance and, by the share's inverse, MuJoCo's own spread
        assert deviation > BAND and deviation >= 2.0 * spread and "MuJoCo's own spread is" in notes[0]
    else:
        assert notes == []


def test_a_divergence_outranks_mujocos_spread():
    divergence = Divergence("settle", 3, 0.006, "a speed of 1e9 m/s")
    found, _ = settled_verdict(_metrics(0.0), np.array([SHARE * 4]), BAND, TOLERANCES, divergence)
    assert found == "diverged"


FALLING = """<mujoco><worldbody>{floor}<body pos="0 0 .5"><freejoint/><geom type="box" size=".1 .1 .1"/></body>
  </worldbody></mujoco>"""


@pytest.mark.parametrize("floor", ['<geom type="plane" size="5 5 .1"/>', ""])
def test_a_contact_tier_says_when_nothing_touched(floor):
    """A box dropped on a floor touches it in MuJoCo's run; without the floor nothing touches, and the contact tier's
    verdict says so beside its pass."""
    from conformance.session import quiet_load
    from conformance.tiers.contact import contact

    spec = mujoco.MjSpec.from_string(FALLING.format(floor=floor))
    result = quiet_load(spec, fix_root_link=False)
    report = contact(result, result.model, 0, TOLERANCES)
    assert report.status == "pass"
    assert (UNTOUCHED in report.notes) == (not floor)


SLIDING = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="5 5 .1" friction="0.3"/>
  <body pos="0 0 .3" euler="0 20 10"><freejoint/><geom name="box" type="box" size=".1 .06 .04" mass="1"
  friction="0.6"/></body></worldbody><keyframe><key qpos="0 0 .3 0.98 0.02 0.17 0.09" qvel="1.5 0.5 0 0 0 3"/>
  </keyframe></mujoco>"""


DRIVEN = SLIDING.replace("<freejoint/>", '<freejoint name="free"/>').replace(
    "</worldbody>", '</worldbody><actuator><motor joint="free" gear="1 0 0 0 0 0" ctrlrange="-2 2"/></actuator>'
)  # the same box pushed along x by a motor under the actuated_contact tier's hold-and-step ctrl


def _tier_report(name: str):
    """The tier `name` on its sliding box document (`SLIDING`, `DRIVEN`)."""
    from conformance.session import quiet_load
    from conformance.tiers.actuated import actuated_contact
    from conformance.tiers.contact import contact

    tier, document = {"contact": (contact, SLIDING), "actuated_contact": (actuated_contact, DRIVEN)}[name]
    result = quiet_load(mujoco.MjSpec.from_string(document), fix_root_link=False)
    return tier(result, result.model, 0, TOLERANCES)


@pytest.mark.parametrize("name", ["contact", "actuated_contact"])
def test_a_contact_rollout_is_judged_step_by_step_where_mujoco_predicts_itself(name, monkeypatch):
    """A tilted box thrown spinning onto a floor lands and slides to rest: MuJoCo's rollout is deterministic, and the
    contact tiers judge SAPIEN's joint positions against it at every step (`rollout_qpos`), not only the settled
    pose. Mutation: the box's friction 8 % low (0.55) in SAPIEN's copy of MuJoCo's contacts only, which the settled
    band alone passes."""
    from loader.runtime.rows import RowTerm

    report = _tier_report(name)
    rollout = next(m for m in report.metrics if m.name == "rollout_qpos")
    assert report.status == "pass" and rollout.passed, report.to_dict()
    mirror = RowTerm.mirror_state

    def lowered(self, step):
        mirror(self, step)
        self.lent.model.geom_friction[self.lent.model.geom("box").id, 0] = 0.55

    monkeypatch.setattr(RowTerm, "mirror_state", lowered)
    report = _tier_report(name)
    band, _, rollout = report.metrics
    assert report.status == "fail" and band.passed and not rollout.passed, report.to_dict()
