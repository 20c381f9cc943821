"""The Python bindings against the library's physics and its other front ends: the default
scene passes through ``run_scene``; a box hanging under gravity settles where the weight it
carries says; positions are NumPy arrays of the right shape; a probe pressed into a block
feels the block push back; errors carry the library's message."""

import math

import numpy as np
import pytest

import lancet


def test_default_scene_runs_and_passes():
    summary = lancet.run_scene()
    assert summary["expectations_passed"] is True
    assert summary["steps"] > 0
    assert summary["max_displacement"] > 0


def test_overrides_change_the_scene_and_bad_ones_name_the_field():
    few = lancet.run_scene(overrides={"steps": 10})
    assert few["steps"] == 10
    with pytest.raises(ValueError, match="no `stepz`"):
        lancet.run_scene(overrides={"stepz": 10})


def test_a_missing_scene_file_names_it():
    with pytest.raises(lancet.LancetError, match="nowhere.ron"):
        lancet.run_scene("/nonexistent/nowhere.ron")


def block(engine="reference", **kw):
    # A 2 cm cube, E = 10 kPa, its base held, under gravity, with mass damping to settle.
    return lancet.World.box(
        size=[0.02, 0.02, 0.02],
        cells=[4, 4, 4],
        youngs_modulus=10e3,
        density=1000.0,
        mass_damping=40.0,
        fixed_box=([-1.0, -1.0, -1e-9], [1.0, 1.0, 1e-9]),
        engine=engine,
        bound_fraction=0.5,
        **kw,
    )


def test_positions_are_an_array_that_moves_under_gravity():
    w = block()
    x0 = w.positions
    assert isinstance(x0, np.ndarray) and x0.shape == (w.node_count, 3) and x0.dtype == np.float64
    np.testing.assert_array_equal(x0, w.rest_positions)
    w.run(400)
    x = w.positions
    top = w.rest_positions[:, 2] > 0.02 - 1e-9
    # The top sinks; the base (held) does not move.
    assert (x[top, 2] < w.rest_positions[top, 2]).all()
    base = w.rest_positions[:, 2] < 1e-9
    np.testing.assert_array_equal(x[base], w.rest_positions[base])


def test_the_settled_column_compresses_as_its_own_weight_says():
    # A column of height L under its own weight: the top sinks rho g L^2 / (2 E') in a
    # laterally free column (E' = E for springs matched in bulk, within the lattice's own
    # stiffness error): check the order of magnitude and the sign, not a copied number.
    w = block()
    w.run(3000)
    sink = (w.rest_positions[:, 2] - w.positions[:, 2])[w.rest_positions[:, 2] > 0.02 - 1e-9].mean()
    expected = 1000.0 * 9.81 * 0.02**2 / (2 * 10e3)
    assert 0.3 * expected < sink < 3.0 * expected, (sink, expected)


def test_a_probe_pressed_into_the_block_feels_it_push_back():
    w = block()
    probe = w.add_tool("probe", "sphere", [0.01, 0.01, 0.0235], radius=0.003)
    forces = []
    for k in range(1, 301):
        w.set_tool_pose(probe, [0.01, 0.01, 0.0235 - 2e-3 * k / 300])
        report = w.step()
        forces.append(report["tools"][probe]["force"][2])
    assert forces[0] == 0.0  # not yet touching
    assert forces[-1] > 0.0  # the tissue pushes the probe up
    assert report["tools"][probe]["contacts"] > 0


def test_the_world_and_the_rust_engines_agree():
    # The reference and fast engines are two implementations of the same model: after the
    # same steps their positions agree to float32 precision of the motion.
    a, b = block("reference"), block("fast")
    a.run(200)
    b.run(200)
    motion = np.abs(a.positions - a.rest_positions).max()
    assert motion > 1e-5
    assert np.abs(a.positions - b.positions).max() < 1e-3 * motion


def test_bad_arguments_raise_value_errors():
    w = block()
    with pytest.raises(ValueError, match="tool 3 does not exist"):
        w.set_tool_pose(3, [0, 0, 0])
    with pytest.raises(ValueError, match="engine `warp`"):
        block("warp")
    with pytest.raises(lancet.LancetError, match="bound"):
        block(dt=1.0)


def test_read_mesh_gives_arrays(tmp_path):
    path = tmp_path / "one.node"
    path.write_text("4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n")
    (tmp_path / "one.ele").write_text("1 4 0\n1 1 2 3 4\n")
    mesh = lancet.read_mesh(path)
    assert mesh.nodes.shape == (4, 3) and mesh.tets.shape == (1, 4)
    assert math.isclose(mesh.volume, 1 / 6)


def test_the_peers_benchmark_world_is_their_model():
    # The box of `lancet bench --preset` (5 cm cells, five tets each, the face x = 0 held,
    # 2e-4 s steps of symplectic Euler). The held face is first felt by the layer of nodes k
    # cells from it at step k + 1 (an explicit step carries news one spring a step, and a
    # cell's springs join neighbouring layers only), so after n steps the layers from n on
    # have fallen freely:
    # symplectic Euler from rest puts it at -g h^2 n (n + 1) / 2 (Verlet would give n^2 / 2).
    w = lancet.World.preset("undamped", (12, 2, 2), engine="fast")
    assert (w.node_count, w.tet_count, w.dt) == (13 * 3 * 3, 12 * 2 * 2 * 5, 2e-4)
    n = 10
    w.run(n, check=False)
    rest, x = w.rest_positions, w.positions
    far = rest[:, 0] > 0.05 * n - 1e-9
    assert far.sum() == 3 * 3 * 3
    fall = 9.81 * 2e-4**2 * n * (n + 1) / 2
    np.testing.assert_allclose(x[far, 2] - rest[far, 2], -fall, rtol=1e-4)
    np.testing.assert_allclose(x[far, :2], rest[far, :2], atol=1e-9)
    held = rest[:, 0] < 1e-9
    np.testing.assert_array_equal(x[held], rest[held])


def test_the_peers_benchmark_world_refuses_what_it_does_not_have():
    with pytest.raises(ValueError, match="preset `stiff`"):
        lancet.World.preset("stiff")
    with pytest.raises(ValueError, match="cells `medium`"):
        lancet.World.preset("damped", "medium")
    with pytest.raises(ValueError, match="split `seven`"):
        lancet.World.preset("damped", (2, 1, 1), split="seven")
    w = block()
    w.add_tool("probe", "sphere", [0.01, 0.01, 0.05], radius=0.003)
    with pytest.raises(ValueError, match="check=False"):
        w.run(1, check=False)
