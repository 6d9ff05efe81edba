"""The articulations' state as the per-step terms read it."""

from __future__ import annotations


def refresh_link_velocities(articulations) -> None:
    """Make a fixed-base articulation's link velocities the ones its joint velocities imply.

    After a step, a fixed-base articulation's links keep the solver's velocities, which carry dt times each
    link's velocity-product acceleration on top of what the new joint velocities imply (a floating base's are
    rebuilt at once). Per-step terms that read link velocities read them after this; writing the joint velocities
    back leaves the dynamics as they are
    (tests/test_loader_connect.py::test_rows_read_on_the_links_drifted_velocities_miss_the_falling_loop)."""
    for articulation in articulations:
        if articulation.dof and articulation.root.joint.type == "fixed":
            articulation.set_qvel(articulation.get_qvel())
