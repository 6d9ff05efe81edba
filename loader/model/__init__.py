"""The shared layer: what the planning half (`loader.plan`) and the per-step half (`loader.runtime`) both read, and
nothing that runs a simulation. The mapping of MuJoCo's bodies, joints and geoms onto SAPIEN, joint kinds and
DoF keys, the records one half hands the other (actuator maps, equality joints), MuJoCo's constants and the options
snapshot, the MuJoCo queries, frames, the drive law and MuJoCo's soft row. It imports neither half
(tests/test_house.py::test_the_tree_keeps_the_house_rules)."""
