"""The DroneCAN node entries a board's CAN1 takes (``FmuV2Board(uavcan_nodes=...)``, a
scenario's ``uavcan_nodes``), parsed in one place so the board and the scenario checker accept
the same set.

An entry is a node ID (int 1..125: a plain node, NodeStatus and GetNodeInfo only) or a kind
with an optional configured node ID, ``"gnss"``, ``"mag"``, ``"esc1"`` .. ``"esc4"``, then
``"@N"`` (1..125; without it, or with ``@0``, the node asks the FMU's allocator for an ID).
"""

from __future__ import annotations

from typing import Final

__all__ = ["NODE_KINDS", "NodeSpec", "parse_node_spec", "check_node_specs"]

NODE_KINDS: Final = ("gnss", "mag", "esc1", "esc2", "esc3", "esc4")
MAX_NODE_ID: Final = 125

#: (kind, node ID): kind "" for a plain node; node ID 0 for "ask the allocator"
NodeSpec = tuple[str, int]


def parse_node_spec(spec: object) -> NodeSpec:
    """``125`` -> ("", 125); ``"esc2@12"`` -> ("esc2", 12); ``"gnss"`` -> ("gnss", 0).
    Anything else raises ValueError saying what is accepted."""
    if isinstance(spec, int) and not isinstance(spec, bool):
        if 1 <= spec <= MAX_NODE_ID:
            return ("", spec)
    elif isinstance(spec, str):
        kind, at, nid = spec.partition("@")
        if kind in NODE_KINDS and (not at or (nid.isdigit() and nid.isascii()
                                              and int(nid) <= MAX_NODE_ID)):
            return (kind, int(nid or 0))
    raise ValueError(f"{spec!r} is not a node ID 1..{MAX_NODE_ID}, 'gnss[@id]', 'mag[@id]' or "
                     f"'esc1'..'esc4[@id]'")


def check_node_specs(specs: list[object] | tuple[object, ...]) -> tuple[NodeSpec, ...]:
    """All entries parsed; a node ID or an ESC number given twice is an error (two nodes
    with one ID fight on the bus; two ESCs with one index drive one motor)."""
    parsed = tuple(parse_node_spec(s) for s in specs)
    ids = [nid for _, nid in parsed if nid]
    kinds = [k for k, _ in parsed if k.startswith("esc")]
    if len(set(ids)) != len(ids):
        raise ValueError(f"node IDs given twice in {list(specs)!r}")
    if len(set(kinds)) != len(kinds):
        raise ValueError(f"an ESC given twice in {list(specs)!r}")
    return parsed
