"""The freeform world's dock welds as a pool: one slot per module (its one connector),
pointed at the module it docks on when the dock happens.

The reference for the pool is MuJoCo itself: a slot re-pointed at run time moves the
bodies exactly as a weld declared for that pair at compile time does. At scale, the
simulator's own state (``eq_active``, ``eq_obj2id``, body centres) is the judge.
"""

from __future__ import annotations

import mujoco
import numpy as np

from msrr.core import plugins
from msrr.core.actions import topology_diff
from msrr.core.configuration import Configuration
from msrr.core.driver import ModuleCommand
from msrr.core.freeform.mujoco import Switches

_SIDE = np.array([0.5, np.sqrt(0.75), 0.0])     # 60 degrees off the row


def _boxes(declared: str) -> tuple[mujoco.MjModel, Switches[str]]:
    """Three free boxes under gravity with one weld slot, declared between A and
    ``declared``."""
    spec = mujoco.MjSpec()
    for i, name in enumerate("ABC"):
        body = spec.worldbody.add_body(name=name, pos=[0.3 * i, 0.1 * i, 1.0 + 0.2 * i])
        body.add_freejoint()
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.05, 0.04, 0.03], mass=0.2 + i)
    switches: Switches[str] = Switches()
    switches.add(spec, "slot", "slot", type=mujoco.mjtEq.mjEQ_WELD,
                 objtype=mujoco.mjtObj.mjOBJ_BODY, name1="A", name2=declared)
    model = spec.compile()
    switches.bind(model)
    return model, switches


def test_a_slot_pointed_at_run_time_holds_as_a_weld_declared_for_the_pair():
    runs = []
    for declared in ("B", "C"):
        model, switches = _boxes(declared)
        data = mujoco.MjData(model)
        data.qvel[:] = np.linspace(-1.0, 1.0, model.nv)   # the weld has work to do
        mujoco.mj_forward(model, data)
        a, b = model.body("A").id, model.body("B").id
        eq = switches.attach(model, "slot", a, b)          # a no-op when declared A-B
        model.eq_data[eq, :3] = 0.0                        # anchor: B's centre
        model.eq_data[eq, 3:6] = data.xmat[a].reshape(3, 3).T @ (data.xpos[b] - data.xpos[a])
        inverse, relative = np.empty(4), np.empty(4)
        mujoco.mju_negQuat(inverse, data.xquat[a])
        mujoco.mju_mulQuat(relative, inverse, data.xquat[b])
        model.eq_data[eq, 6:10], model.eq_data[eq, 10] = relative, 1.0
        switches.on(data, "slot")
        for _ in range(300):
            mujoco.mj_step(model, data)
        assert list(switches.active(data)) == ["slot"]
        runs.append(data.qpos.copy())
    np.testing.assert_allclose(runs[1], runs[0], atol=1e-12)
    # and the weld held: A and B kept their distance while both moved
    a, b = runs[0][0:3], runs[0][7:10]
    assert np.linalg.norm(a - [0.0, 0.0, 1.0]) > 0.1
    assert abs(np.linalg.norm(b - a) - np.linalg.norm([0.3, 0.1, 0.2])) < 1e-3


def _triangles(count: int) -> Configuration:
    """``count`` groups of three FreeBOTs: ``a -> b`` along x and ``c -> b`` at 60
    degrees, so that ``c`` touches ``a`` too."""
    config = Configuration("freebot", name=f"triangles{count}")
    for g in range(count):
        for m in "abc":
            config.add_module(f"{m}{g}", "freebot")
        config.connect(f"a{g}", f"b{g}", z=[1.0, 0.0, 0.0])
        config.connect(f"c{g}", f"b{g}", z=_SIDE.tolist())
    return config


def test_a_world_of_hundreds_declares_one_slot_a_module_and_docks_each_where_it_touches():
    count = 70                                  # 210 modules (43,890 welds declared per pair)
    driver = plugins.drivers.get("freebot", "mujoco")()
    driver.connect()
    try:
        driver.reset(_triangles(count))
        world = driver.world
        assert world.model.neq == 3 * count
        # every c lets go of b and docks on a, which it touches
        driver.send_action({f"c{g}": ModuleCommand(undock=(f"@b{g}",)) for g in range(count)})
        driver.step(0.05)
        assert world.docked_pairs() == {(f"a{g}", f"b{g}") for g in range(count)}
        driver.send_action({f"c{g}": ModuleCommand(dock=(f"@a{g}",)) for g in range(count)})
        driver.step(0.3)
        goal = Configuration("freebot")
        for g in range(count):
            for m in "abc":
                goal.add_module(f"{m}{g}", "freebot")
            goal.connect(f"a{g}", f"b{g}", z=[1.0, 0.0, 0.0])
            goal.connect(f"c{g}", f"a{g}", z=[-0.5, -np.sqrt(0.75), 0.0])
        truth = world.ground_truth()
        assert not topology_diff(truth, goal)
        slots = [world.welds.id(f"c{g}") for g in range(count)]
        assert list(world.model.eq_obj2id[slots]) == [world.bodies[f"a{g}"] for g in range(count)]
        assert world.constraint_residual() < 1e-3                      # [m]
        assert driver.constraint_events() == {"dock": count, "undock": count, "flow": 0}
    finally:
        driver.disconnect()
