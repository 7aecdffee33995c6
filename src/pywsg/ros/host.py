"""What the node's parts (the GripperCommand server, the legacy interface) use of the node: a narrow
Protocol, so they never import the node module (which makes them)."""

from __future__ import annotations

from typing import Any, Protocol

from ..client import Gripper
from .live import Live
from .params import Settings


class NodeHost(Protocol):
    """:class:`~pywsg.ros.node.WsgNode` as its parts see it (also an rclpy Node: ``create_service`` ...)."""

    settings: Settings
    gripper: Gripper | None
    live: Live
    group: Any  # the reentrant callback group of the node's services and action
    stroke: float  # mm
    acceleration: float  # mm/s²

    def ready(self) -> bool: ...

    def note_error(self, exc: BaseException) -> None: ...

    def destroy_entity(self, entity: Any) -> None: ...

    def get_logger(self) -> Any: ...

    def create_service(self, *args: Any, **kwargs: Any) -> Any: ...

    def create_subscription(self, *args: Any, **kwargs: Any) -> Any: ...

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any: ...
