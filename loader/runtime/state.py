"""The articulations' state as the per-step terms read it."""

from __future__ import annotations


def refresh_link_velocities(articulations) -> None:
    """Make a fixed-base articulation's link velocities the ones its joint velocities imply.

    Measured, and PhysX's source says why: after a step, a fixed-base articulation's links keep the solver's
    velocities, which carry dt times each link's velocity-product acceleration on top of what the new joint
    velocities imply (1.4e-5 m/s on a slide of tests/fixtures/turning_slide.xml; the next step rebuilds them from
    the joint velocities, a floating base's are rebuilt at once). Per-step terms that read link velocities
    (connect and weld rows, fluid, slides) read them after this: the closed five-bar's rollouts 1.2e-5 -> 7.9e-7
    rad. Writing the joint velocities back leaves the dynamics as they are."""
    for articulation in articulations:
        if articulation.dof and articulation.root.joint.type == "fixed":
            articulation.set_qvel(articulation.get_qvel())
