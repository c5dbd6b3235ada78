"""The mission behaviour-tree engine: pure functions over a mission tree and its stored node states.

It reproduces the reference's py_trees 2.1.6 tree without keeping a live tree in memory. Leaf results are
stored in ``node_status``, so evaluating the whole tree from its root over those states gives the same
result py_trees reaches with its remembered progress: a memory sequence skips children that already
succeeded, and evaluating them again returns the same SUCCESS. This is what lets any worker step any
mission after a restart.

- The mission tree has an implicit root ``sequence`` named ``"root"``.
- ``sequence`` (py_trees ``Sequence(memory=True)``): children in order, fails on the first failure,
  succeeds when all succeed; with no children it succeeds.
- ``selector`` (py_trees ``Selector(memory=False)``): children from the first, succeeds on the first
  success, fails when all fail; with no children it fails.
- route/move/action/notify leaves (``LEAF_KINDS``) read their stored state: PENDING and RUNNING are
  running, COMPLETED is success, FAILED and CANCELED are failure. The caller executes them and writes
  their results; the engine never changes a leaf's state except in ``finish``.
- ``constant`` returns its fixed ``success`` (default true) immediately.
- After a tick, the state of every composite and constant that was evaluated is written to
  ``node_status`` and ``root`` mirrors the mission state; nodes not evaluated keep their stored state, so
  skipped leaves stay PENDING.
- The tip (py_trees ``tip()``) is the deepest node on the last evaluated path: the running leaf while
  the mission runs, the last evaluated node once it is done. ``current_node`` is its index in
  ``mission_tree``; it can be a constant or an empty composite when that is where evaluation ended.

No I/O, and no Django, paho or Redis imports: states and kinds are the vocabulary's ``MissionState`` and
``NodeKind`` (``dispatch.vocabulary``), which compare equal to the API's plain strings stored in JSON.
"""

from __future__ import annotations

import copy
import enum
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

from dispatch.vocabulary import DONE_STATES, MissionState, NodeKind

__all__ = [
    "COMPOSITE_KINDS",
    "KINDS",
    "LEAF_KINDS",
    "ROOT",
    "STATES",
    "Node",
    "TickResult",
    "Tree",
    "TreeError",
    "apply_route_updates",
    "finish",
    "initial_node_status",
    "next_leaf",
    "parse_tree",
    "set_leaf_state",
    "tick",
]

STATES = frozenset(MissionState)
# Every node kind, as plain strings in the vocabulary's order (error messages list them).
KINDS = tuple(kind.value for kind in NodeKind)
COMPOSITE_KINDS = frozenset({NodeKind.SELECTOR, NodeKind.SEQUENCE})
# Leaves the caller executes (an order for the robot, or the notify call); a constant resolves itself.
LEAF_KINDS = frozenset({NodeKind.ROUTE, NodeKind.MOVE, NodeKind.ACTION, NodeKind.NOTIFY})

ROOT = "root"


class TreeError(ValueError):
    """A mission tree or node status the engine cannot work with; the message is fit for failure_reason."""


class _Outcome(enum.Enum):
    """py_trees' status of a ticked node; its value is the state it stores."""

    RUNNING = MissionState.RUNNING
    SUCCESS = MissionState.COMPLETED
    FAILURE = MissionState.FAILED


_LEAF_OUTCOMES = {
    MissionState.PENDING: _Outcome.RUNNING,  # not acknowledged by the robot yet, or not started: running
    MissionState.RUNNING: _Outcome.RUNNING,
    MissionState.COMPLETED: _Outcome.SUCCESS,
    MissionState.FAILED: _Outcome.FAILURE,
    MissionState.CANCELED: _Outcome.FAILURE,
}


@dataclass(frozen=True)
class Node:
    """One node of a mission tree; ``params`` is the node's kind payload (treat it as read-only)."""

    name: str
    parent: str
    kind: str
    params: dict[str, Any] = field(hash=False)
    index: int | None  # position in mission_tree; None for the implicit root
    children: tuple[str, ...] = ()


@dataclass(frozen=True)
class Tree:
    """A parsed mission tree: the implicit root plus the nodes in ``mission_tree`` order."""

    root: Node
    nodes: tuple[Node, ...]

    @cached_property
    def _by_name(self) -> dict[str, Node]:
        return {node.name: node for node in (self.root, *self.nodes)}

    def node(self, name: str) -> Node:
        """The node called ``name`` (``"root"`` included)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise TreeError(f"Node {name} does not exist") from None


@dataclass(frozen=True)
class TickResult:
    """What a tick (or ``finish``) decided: new node states, mission state and the current leaf.

    ``current_leaf`` is the leaf to execute while the mission runs and None once it is done; in PENDING
    state it has not been started yet (see ``leaf_to_start``). ``current_node`` is the tip's index in
    ``mission_tree``, None when nothing was evaluated (an empty tree, or a mission that had already ended).
    """

    node_status: dict[str, dict[str, Any]] = field(hash=False)
    mission_state: str
    current_node: int | None
    current_leaf: Node | None

    @property
    def leaf_to_start(self) -> Node | None:
        """The current leaf if it still has to be started: the caller sets it RUNNING and executes it."""
        leaf = self.current_leaf
        if leaf is not None and self.node_status[leaf.name]["state"] == MissionState.PENDING:
            return leaf
        return None


def parse_tree(mission_tree: list[dict[str, Any]]) -> Tree:
    """Build a Tree from ``mission_tree`` in the API's shape, checking it is a tree the engine can run.

    The API validates trees too, but a stored tree is checked again so a bad one fails the mission
    with a clear reason instead of crashing the worker. Unnamed nodes are named by their index.
    """
    nodes: list[Node] = []
    children: dict[str, list[str]] = {ROOT: []}
    kinds: dict[str, str] = {ROOT: NodeKind.SEQUENCE}
    for index, raw in enumerate(mission_tree):
        if not isinstance(raw, Mapping):
            raise TreeError(f"MissionNode {index} must be an object, not {type(raw).__name__}")
        name = raw.get("name")
        name = str(index) if name is None else name
        parent = raw.get("parent", ROOT)
        if not isinstance(name, str) or not isinstance(parent, str):
            raise TreeError(f"MissionNode {index} must have string name and parent")
        if name == ROOT:
            raise TreeError(f"MissionNode name {ROOT} is reserved for the implicit root sequence")
        if name in kinds:
            raise TreeError(f"MissionNode name {name} is repeated. All MissionNode names must be unique.")
        if parent not in kinds:
            raise TreeError(f"Given parent {parent} does not exist")
        if kinds[parent] not in COMPOSITE_KINDS:
            raise TreeError(f"Given parent {parent} is a {kinds[parent]} node, which cannot have children")
        set_kinds = [kind for kind in KINDS if raw.get(kind) is not None]
        if len(set_kinds) != 1:
            raise TreeError(
                f"Exactly one of the following must be set {list(KINDS)}, "
                f"but the following {len(set_kinds)} are set {set_kinds}"
            )
        kind = set_kinds[0]
        params = raw[kind]
        if not isinstance(params, Mapping):
            raise TreeError(f"MissionNode {name}: {kind} must be an object")
        if kind == NodeKind.CONSTANT and not isinstance(params.get("success", True), bool):
            raise TreeError(f"MissionNode {name}: constant success must be true or false")
        params = copy.deepcopy(dict(params))
        nodes.append(Node(name=name, parent=parent, kind=kind, params=params, index=index))
        kinds[name] = kind
        children[name] = []
        children[parent].append(name)
    return Tree(
        root=Node(
            name=ROOT,
            parent="",
            kind=NodeKind.SEQUENCE,
            params={},
            index=None,
            children=tuple(children[ROOT]),
        ),
        nodes=tuple(replace(node, children=tuple(children[node.name])) for node in nodes),
    )


def initial_node_status(tree: Tree) -> dict[str, dict[str, Any]]:
    """Node states of a mission that has not started: root and every node PENDING, no error message."""
    return {
        node.name: {"state": MissionState.PENDING, "error_msg": None} for node in (tree.root, *tree.nodes)
    }


def tick(tree: Tree, node_status: Mapping[str, Mapping[str, Any]]) -> TickResult:
    """Evaluate the tree once over the stored node states; ``node_status`` is not modified.

    A mission that has already ended (root COMPLETED, FAILED or CANCELED) is not evaluated again: its
    states come back unchanged with no current leaf. A CANCELED leaf counts as a failure, so a leaf
    canceled only to resend it (route update) must be set back to PENDING, not ticked over.
    """
    status = _copy_status(tree, node_status)
    root_state = status[ROOT]["state"]
    if root_state in DONE_STATES:
        return TickResult(node_status=status, mission_state=root_state, current_node=None, current_leaf=None)
    outcome, tip = _evaluate(tree, tree.root, status)
    return TickResult(
        node_status=status,
        mission_state=outcome.value,
        current_node=tip.index,
        current_leaf=tip if outcome is _Outcome.RUNNING else None,
    )


def finish(
    tree: Tree, node_status: Mapping[str, Mapping[str, Any]], *, state: str, error_msg: str | None = None
) -> TickResult:
    """End a mission as CANCELED (canceled by the user) or FAILED (timeout, deadline, robot removed).

    The running leaf, if any, takes ``state`` (and ``error_msg`` when given) and root takes ``state``;
    every other node keeps its stored state. A leaf that was never started stays PENDING. A mission that
    has already ended is returned unchanged, as ``tick`` does.
    """
    if state not in (MissionState.CANCELED, MissionState.FAILED):
        raise TreeError(
            f"A mission can only be finished as {MissionState.CANCELED} or {MissionState.FAILED}, not {state}"
        )
    status = _copy_status(tree, node_status)
    if status[ROOT]["state"] in DONE_STATES:
        return tick(tree, status)
    outcome, tip = _evaluate(tree, tree.root, _copy_status(tree, status))  # only to find the tip
    if outcome is _Outcome.RUNNING and status[tip.name]["state"] == MissionState.RUNNING:
        status = set_leaf_state(status, tip.name, state, error_msg)
    status[ROOT]["state"] = state
    return TickResult(node_status=status, mission_state=state, current_node=tip.index, current_leaf=None)


def next_leaf(tree: Tree, node_status: Mapping[str, Mapping[str, Any]], leaf: str) -> Node | None:
    """The leaf a tick starts once the running leaf ``leaf`` succeeds; None if the mission ends then.

    Certain, not a guess: everything a tick evaluates on the way from ``leaf`` to the next leaf is a
    composite or a constant, whose outcomes follow from the stored leaf states alone, and a leaf's state
    changes only when it runs. A result of ``leaf`` other than success (failure, cancel), or the mission
    ending from outside (cancel, timeout, deadline), is the only way another leaf, or none, comes next.
    """
    after = tick(tree, set_leaf_state(_copy_status(tree, node_status), leaf, MissionState.COMPLETED))
    return after.leaf_to_start


def set_leaf_state(
    node_status: Mapping[str, Mapping[str, Any]], name: str, state: str, error_msg: str | None = None
) -> dict[str, dict[str, Any]]:
    """A copy of ``node_status`` with ``name`` in ``state``; a given ``error_msg`` replaces the old one."""
    if state not in STATES:
        raise TreeError(f"Unknown node state {state}")
    if name not in node_status:
        raise TreeError(f"Node {name} does not exist")
    status = {node_name: dict(entry) for node_name, entry in node_status.items()}
    status[name]["state"] = state
    if error_msg is not None:
        status[name]["error_msg"] = error_msg
    return status


def apply_route_updates(tree: Tree, update_nodes: Mapping[str, Mapping[str, Any]] | None) -> Tree:
    """The tree with each named route node's params replaced by its update (``spec.update_nodes``)."""
    if not update_nodes:
        return tree
    for name in update_nodes:
        node = tree.node(name)
        if node.kind != NodeKind.ROUTE:
            raise TreeError(f"Only route nodes can be updated, but {name} is a {node.kind} node")
    nodes = tuple(
        replace(node, params=copy.deepcopy(dict(update_nodes[node.name])))
        if node.name in update_nodes
        else node
        for node in tree.nodes
    )
    return Tree(root=tree.root, nodes=nodes)


def _copy_status(tree: Tree, node_status: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """A deep enough copy to write into, with a PENDING entry for any node the stored status lacks."""
    status = initial_node_status(tree)
    for name, entry in node_status.items():
        status[name] = {"state": MissionState.PENDING, "error_msg": None, **entry}
    return status


def _evaluate(tree: Tree, node: Node, status: dict[str, dict[str, Any]]) -> tuple[_Outcome, Node]:
    """Tick ``node``'s subtree as py_trees does: its outcome and tip; writes composite/constant states."""
    if node.kind in LEAF_KINDS:
        state = status[node.name]["state"]
        if state not in _LEAF_OUTCOMES:
            raise TreeError(f"Node {node.name} has unknown state {state}")
        return _LEAF_OUTCOMES[state], node
    if node.kind == NodeKind.CONSTANT:
        outcome, tip = (_Outcome.SUCCESS if node.params.get("success", True) else _Outcome.FAILURE), node
    else:
        outcome, tip = _evaluate_composite(tree, node, status)
    status[node.name]["state"] = outcome.value
    return outcome, tip


def _evaluate_composite(tree: Tree, node: Node, status: dict[str, dict[str, Any]]) -> tuple[_Outcome, Node]:
    """A sequence stops at the first child that does not succeed, a selector at the first that does not fail.

    Running off the end leaves the last child's outcome (SUCCESS for a sequence, FAILURE for a selector)
    and its tip; with no children a sequence succeeds and a selector fails, and the tip is the node itself.
    """
    passes = _Outcome.SUCCESS if node.kind == NodeKind.SEQUENCE else _Outcome.FAILURE
    outcome, tip = passes, node
    for child_name in node.children:
        outcome, tip = _evaluate(tree, tree.node(child_name), status)
        if outcome is not passes:
            break
    return outcome, tip
