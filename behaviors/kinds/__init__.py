"""Node kinds: every composite, decorator and leaf a tree can hold, registered by name."""

from botstage.behaviors.kinds.base import (
    CompositeKind,
    DecoratorKind,
    Described,
    KindOptions,
    LeafKind,
    NodeBuild,
    NodeKind,
    NoOptions,
)
from botstage.behaviors.kinds.registry import ENTRY_POINT_GROUP, NodeKinds

__all__ = [
    "ENTRY_POINT_GROUP",
    "CompositeKind",
    "DecoratorKind",
    "Described",
    "KindOptions",
    "LeafKind",
    "NoOptions",
    "NodeBuild",
    "NodeKind",
    "NodeKinds",
]
