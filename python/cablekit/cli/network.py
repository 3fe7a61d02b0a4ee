"""``cablekit network``: the shipped cable networks, and a network file checked and described."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

#: share below which the tension closure counts as absent (the LP's tolerance)
CLOSURE_TOL = 1e-6


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "network",
        help="cable networks from model files: list the shipped ones, check and describe a file",
        description="A network model file (docs/models.md) read and checked: its elements, the moment-arm "
        "matrix of its routing, its rank and conditioning, the tension closure (whether every cable can be "
        "pretensioned without moving the mechanism), the model's state, input and output layout and its "
        "sensors. Exit 4 on a file that does not describe a valid mechanism (the element is named).",
    )
    s = p.add_subparsers(dest="network_command", required=True)
    s.add_parser("list", help="the shipped networks").set_defaults(func=_list)
    c = s.add_parser("check", help="check and describe a network file (or a shipped network by name)")
    c.add_argument("network", help="a TOML network file, or the name of a shipped network")
    c.add_argument("--json", metavar="FILE", help="also write the description as JSON")
    c.set_defaults(func=_check)


def _list(args: argparse.Namespace) -> int:
    from cablekit import network

    for name in network.shipped_names():
        doc = network.shipped_document(name)
        print(f"{name:<20} {doc['description'].split(':')[0].splitlines()[0]}")
    return 0


def _load(what: str) -> tuple[Any, dict[str, Any]]:
    from cablekit import network
    from cablekit._files import load_toml

    if not Path(what).suffix and what in network.shipped_names():
        doc = network.shipped_document(what)
    else:
        doc = load_toml(what, "network file")
    return network.from_dict(doc, what), doc


def describe(net: Any, doc: dict[str, Any]) -> dict[str, Any]:
    """The description ``cablekit network check`` prints: elements, moment arms, closure."""
    arms = np.asarray(net.moment_arms)
    sv = np.linalg.svd(arms, compute_uv=False)
    share, tensions = net.tension_closure()
    return {
        "name": doc.get("name", ""),
        "reference": doc.get("reference", ""),
        "joints": net.joint_names,
        "cables": net.cable_names,
        "motors": net.motor_names,
        "moment_arms_m": arms.tolist(),
        "singular_values": sv.tolist(),
        "condition_number": float(sv[0] / sv[-1]),
        "tension_closure": {
            "closed": bool(share > CLOSURE_TOL),
            "smallest_share": float(share),
            "tensions": np.asarray(tensions).tolist(),
        },
        "states": net.state_names,
        "inputs": net.input_names,
        "outputs": net.output_names,
        "sensors": {name: net.output_names[i] for name, i in net.sensors},
    }


def _check(args: argparse.Namespace) -> int:
    net, doc = _load(args.network)
    d = describe(net, doc)
    counts = f"{len(d['joints'])} joints, {len(d['cables'])} cables, {len(d['motors'])} motors"
    print(f"{d['name'] or args.network}: {counts}")
    if d["reference"]:
        print(f"  reference: {d['reference']}")
    width = max(len(c) for c in d["cables"])
    print("  moment arms J (mm), cable x joint: " + "  ".join(f"{j:>8}" for j in d["joints"]))
    for c, row in zip(d["cables"], d["moment_arms_m"], strict=True):
        print(f"    {c:<{width}} " + "  ".join(f"{1e3 * v:8.3f}" for v in row))
    print("  its tension turns (sense +1: positively; check the signs against the mechanism):")
    for c, row in zip(d["cables"], d["moment_arms_m"], strict=True):
        pulls = ", ".join(f"{j} {'+' if v > 0 else '-'}" for j, v in zip(d["joints"], row, strict=True) if v)
        print(f"    {c:<{width}} {pulls}")
    print(
        f"  rank {len(d['joints'])} of {len(d['joints'])} (singular values "
        + ", ".join(f"{v:.3g}" for v in d["singular_values"])
        + f"; condition number {d['condition_number']:.3g})"
    )
    tc = d["tension_closure"]
    shares = ", ".join(f"{c} {t:.3f}" for c, t in zip(d["cables"], tc["tensions"], strict=True))
    if tc["closed"]:
        print(f"  tension closure: yes — every cable can be pretensioned with no joint torque ({shares})")
    else:
        print(
            "  tension closure: NO — a torque-free state needs a cable to push "
            f"({shares}): the mechanism cannot be fully pretensioned"
        )
    print(f"  states:  {', '.join(d['states'])}")
    print(f"  inputs:  {', '.join(d['inputs'])}")
    print(f"  outputs: {', '.join(d['outputs'])}")
    if d["sensors"]:
        print("  sensors: " + ", ".join(f"{k} = {v}" for k, v in d["sensors"].items()))
    if args.json:
        Path(args.json).write_text(json.dumps(d, indent=1))
        print(f"  wrote {args.json}")
    return 0
