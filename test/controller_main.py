"""
The main() of the test controllers: init, spin one node until Ctrl-C or shutdown, clean up.

The controller scripts in ``test/`` are started as processes (``python test/NAME.py``), so
their folder is on ``sys.path`` and they import this module as a sibling.
"""
from __future__ import annotations

from typing import Callable

import rclpy


def spin(make_node: Callable[[], 'rclpy.node.Node'], args=None) -> None:
    """Initialise rclpy with ``args``, spin the node ``make_node()`` returns, then shut down."""
    rclpy.init(args=args)
    node = make_node()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
