"""The node's pose-graph back-end, in a process of its own (GTSAM holds the GIL while it
optimises: in the node's process it would stall the subscription callbacks).

:func:`serve` answers each ``(odometry poses (N, 4, 4), loops)`` it receives with the optimum
``(N, 4, 4)`` of the graph :func:`solid.slam.odometry_graph` + :func:`solid.slam.add_loop_edges`
makes of them, until it receives None.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np

__all__ = ["loop_record", "serve"]


def loop_record(lp: Any) -> SimpleNamespace:
    """What the back-end needs of a loop (ids, pose, information), picklable."""
    return SimpleNamespace(query=int(lp.query), candidate=int(lp.candidate), pose=lp.pose, information=lp.information)


def serve(conn: Any, robust: str) -> None:
    from ..slam import add_loop_edges, odometry_graph, optimize_graph

    while True:
        try:
            job = conn.recv()
        except (EOFError, KeyboardInterrupt):
            return
        if job is None:
            return
        P, loops = job
        graph = odometry_graph(np.arange(len(P)), P)
        add_loop_edges(graph, loops, 0)
        optimum, _ = optimize_graph(graph, robust)
        conn.send(optimum)
