"""parse_tree: the tree shape the engine builds, and the stored trees it refuses with a clear reason."""

import copy

import pytest

from dispatch.engine import ROOT, TreeError, parse_tree
from dispatch.vocabulary import NodeKind

from .trees import action, constant, route, selector, sequence


def test_nodes_keep_list_order_index_kind_and_params():
    mission_tree = [route("a"), selector("s"), action("b", "s"), constant("k", False, "s")]
    tree = parse_tree(mission_tree)
    assert [(n.name, n.parent, n.kind, n.index) for n in tree.nodes] == [
        ("a", ROOT, "route", 0),
        ("s", ROOT, "selector", 1),
        ("b", "s", "action", 2),
        ("k", "s", "constant", 3),
    ]
    assert tree.node("a").params == mission_tree[0]["route"]
    assert tree.node("k").params == {"success": False}


def test_children_in_list_order_under_an_implicit_root_sequence():
    tree = parse_tree([sequence("q"), route("b", "q"), route("c"), route("a", "q")])
    assert (tree.root.name, tree.root.kind, tree.root.index) == (ROOT, NodeKind.SEQUENCE, None)
    assert tree.root.children == ("q", "c")
    assert tree.node("q").children == ("b", "a")
    assert tree.node("c").children == ()
    assert tree.node(ROOT) is tree.root


def test_unnamed_nodes_are_named_by_index_and_parent_defaults_to_root():
    tree = parse_tree([{"selector": {}}, {"parent": "0", "route": {"waypoints": []}}])
    assert [(n.name, n.parent) for n in tree.nodes] == [("0", ROOT), ("1", "0")]


def test_other_kind_keys_set_to_null_are_ignored():
    node = {"name": "a", "parent": ROOT, "route": {"waypoints": []}, "action": None, "selector": None}
    assert parse_tree([node]).node("a").kind == "route"


def test_params_are_copied_from_the_input():
    mission_tree = [route("a")]
    before = copy.deepcopy(mission_tree)
    tree = parse_tree(mission_tree)
    mission_tree[0]["route"]["waypoints"].append({"x": 9.0})
    assert mission_tree != before
    assert tree.node("a").params == before[0]["route"]


def test_unknown_node_name_lookup():
    with pytest.raises(TreeError, match="Node nope does not exist"):
        parse_tree([route("a")]).node("nope")


@pytest.mark.parametrize(
    ("mission_tree", "message"),
    [
        pytest.param([route("a"), route("a")], "MissionNode name a is repeated", id="duplicate name"),
        pytest.param([route(ROOT)], "MissionNode name root is reserved", id="reserved root name"),
        pytest.param([route("a", "ghost")], "Given parent ghost does not exist", id="unknown parent"),
        pytest.param(
            [route("a", "s"), selector("s")], "Given parent s does not exist", id="parent after the child"
        ),
        pytest.param([sequence("q", "q")], "Given parent q does not exist", id="node is its own parent"),
        pytest.param(
            [route("a"), route("b", "a")],
            "Given parent a is a route node, which cannot have children",
            id="leaf as parent",
        ),
        pytest.param(
            [constant("k", True), route("b", "k")],
            "Given parent k is a constant node",
            id="constant as parent",
        ),
        pytest.param(
            [{"name": "a", "parent": ROOT}],
            r"Exactly one of the following must be set .*but the following 0",
            id="no kind",
        ),
        pytest.param(
            [{"name": "a", "route": {"waypoints": []}, "action": {"action_type": "x"}}],
            r"but the following 2 are set \['route', 'action'\]",
            id="two kinds",
        ),
        pytest.param([{"name": "a", "teleport": {}}], "but the following 0 are set", id="unknown kind only"),
        pytest.param([["route"]], "MissionNode 0 must be an object", id="node not an object"),
        pytest.param(
            [{"name": 7, "sequence": {}}], "must have string name and parent", id="name not a string"
        ),
        pytest.param(
            [{"name": "a", "route": [1, 2]}], "MissionNode a: route must be an object", id="bad params"
        ),
        pytest.param(
            [{"name": "k", "constant": {"success": "false"}}],
            "constant success must be true or false",
            id="constant success not a boolean",
        ),
    ],
)
def test_invalid_trees_are_refused(mission_tree, message):
    with pytest.raises(TreeError, match=message):
        parse_tree(mission_tree)
