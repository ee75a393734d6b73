"""Controllers × world lifecycle compositions: what a controller sees of nodes and of the other controllers as
robots are removed, imported, reset and run with and without synchronisation.

References: webots-python-api.md (Supervisor.getFromId "unique node id", Node.remove "delete"),
webots-on-ode.md §6 (simulationReset: added nodes removed), webots-devices.md §11.3.
"""

from __future__ import annotations

from tests.support.quiet_worlds import quiet_supervisor

TS = 8
NODES_WORLD = f"""#VRML_SIM R2023b utf8
WorldInfo {{ basicTimeStep {TS} }}
DEF BOSS Robot {{ name "boss" supervisor TRUE }}
DEF BOT Robot {{ translation 1 0 0 name "bot" children [ DEF INNER Solid {{ name "inner" }} ] }}
DEF BOX Solid {{ translation 0 2 0 name "box" }}
"""


def test_get_from_id_no_longer_finds_a_removed_node_or_its_descendants() -> None:
    # Node.remove deletes the node: as getFromDef, getFromId then finds neither it nor what it held, while the
    # nodes left in the world are still found by their ids (ids are never given to another node)
    sup = quiet_supervisor(NODES_WORLD)
    bot, inner, box = (sup.getFromDef(name) for name in ("BOT", "INNER", "BOX"))
    ids = {name: node.getId() for name, node in (("BOT", bot), ("INNER", inner), ("BOX", box))}
    assert sup.getFromId(ids["BOT"]) == bot and sup.getFromId(ids["INNER"]) == inner
    bot.remove()
    assert sup.getFromDef("BOT") is None
    assert sup.getFromId(ids["BOT"]) is None and sup.getFromId(ids["INNER"]) is None
    sup.step(TS)
    assert sup.getFromId(ids["BOT"]) is None and sup.getFromId(ids["INNER"]) is None
    assert sup.getFromId(ids["BOX"]) == box and sup.getFromId(sup.getSelf().getId()) == sup.getSelf()


def test_get_from_id_no_longer_finds_a_node_the_reset_took_out() -> None:
    # simulationReset removes the nodes added since the load (webots-on-ode.md §6, webots-devices.md §11.3)
    sup = quiet_supervisor(NODES_WORLD)
    children = sup.getRoot().getField("children")
    children.importMFNodeFromString(-1, 'DEF ADDED Solid { translation 0 -2 0 name "added" }')
    added = sup.getFromDef("ADDED")
    assert added is not None and sup.getFromId(added.getId()) == added
    sup.step(TS)
    sup.simulationReset()
    sup.step(TS)  # the reset is applied at the end of this step
    assert sup.getFromDef("ADDED") is None and sup.getFromId(added.getId()) is None
