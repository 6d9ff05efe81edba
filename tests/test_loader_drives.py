"""The drive writer's PhysX calls (loader/runtime/drive_writer.py): it skips the settings that did not change since
its last write, and PhysX still holds every step's law."""

import mujoco
import numpy as np
import pytest

from loader import MJCFLoader
from loader.runtime.drive_writer import DriveWriter

SERVO = """<mujoco><option timestep="0.002" integrator="implicitfast"/>
  <worldbody><body name="arm" pos="0 0 1"><joint name="hinge" axis="0 1 0" damping="0.1"/>
    <geom type="capsule" fromto="0 0 0 .3 0 0" size=".02" mass=".5"/></body></worldbody>
  <actuator><position name="servo" joint="hinge" kp="10" kv="1" ctrlrange="-1 1"/></actuator>
</mujoco>"""


def _never_rewritten(monkeypatch) -> None:
    """The mistake: after its first write the writer remembers new settings without writing them."""
    write = DriveWriter.write

    def first_only(self, settings):
        if np.isnan(self.written).all():
            write(self, settings)
        else:
            self.written = settings

    monkeypatch.setattr(DriveWriter, "write", first_only)


@pytest.mark.usefixtures("terms")
@pytest.mark.parametrize("writes", ["changed", "mistake_never_rewritten"])
def test_a_changed_target_or_gain_reaches_physx_after_a_cached_step(monkeypatch, writes):
    """A position servo (kp 10, kv 1 on 0.1 passive damping; dt 0.002): target ctrl, stiffness kp, damping
    0.1 + kv - kp dt. The same ctrl twice (the second step writes nothing), a new ctrl, kp doubled through
    `controller.laws()` (target kp ctrl / 2 kp), and `release()` then `set_ctrl` again: after each, PhysX's drive
    is the law's."""
    if writes != "changed":
        _never_rewritten(monkeypatch)
    result = MJCFLoader().load(mujoco.MjSpec.from_string(SERVO))
    joint = result.articulations[0].active_joints[0]
    seen, expected = [], []

    def check(target: float, stiffness: float) -> None:
        seen.append((float(np.asarray(joint.drive_target).ravel()[0]), joint.stiffness, joint.damping))
        expected.append((target, stiffness, 1.1 - stiffness * 0.002))

    for ctrl in (0.3, 0.3, -0.5):
        result.set_ctrl([ctrl])
        check(ctrl, 10.0)
        result.scene.step()
    for law in result.controller.edit_laws().values():
        law.stiffness *= 2.0
    result.set_ctrl([-0.5])
    check(-0.25, 20.0)
    result.release()
    result.set_ctrl([0.4])
    check(0.2, 20.0)
    agree = np.allclose(seen, expected, rtol=1e-6, atol=1e-7)
    assert agree == (writes == "changed"), (seen, expected)


def _held(articulation, layout, forces, write) -> np.ndarray:
    """The `qf` PhysX holds after `write` of each row of `forces`."""
    step = type("Step", (), {"articulations": [articulation], "layout": layout})()
    held = []
    for force in forces:
        step.force = force
        write(step)
        held.append(articulation.get_qf().copy())
    return np.array(held)


def test_qf_is_written_as_float64_and_held_as_its_float32_rounding():
    """`write_qf` hands SAPIEN the float64 forces: PhysX holds each rounded to the nearest float32, as `astype`
    rounds it, over magnitudes from 1e-40 (subnormal in float32) to 1e38. A writer that rounds more coarsely on
    the way (through float16) holds other forces."""
    from loader.runtime.dof_step import DofLayout

    result = MJCFLoader().load(mujoco.MjSpec.from_string(SERVO))
    articulation = result.articulations[0]
    layout = DofLayout(result.articulations, [])
    rng = np.random.default_rng(0)
    forces = rng.standard_normal((500, articulation.dof)) * 10.0 ** rng.integers(-40, 39, (500, articulation.dof))
    expected = forces.astype(np.float32)
    assert np.array_equal(_held(articulation, layout, forces, DriveWriter.write_qf), expected)

    def coarse(step):
        articulation.set_qf(step.force.astype(np.float16).astype(np.float32))

    with np.errstate(over="ignore"):
        assert not np.array_equal(_held(articulation, layout, forces, coarse), expected)
