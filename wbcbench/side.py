"""Which foot: one enum instead of left/right twins."""

from __future__ import annotations

import enum


class Side(str, enum.Enum):
    """A foot (or any left/right pair). `sign` is +1 for LEFT, -1 for RIGHT (the y direction of its offset).

    A str enum with the values "left" / "right". It lives at the package top level, free of dependencies, so
    that planning and stabilizers can use it without importing the robot model.
    """

    LEFT = "left"
    RIGHT = "right"

    @property
    def other(self) -> "Side":
        """The opposite side."""
        return Side.RIGHT if self is Side.LEFT else Side.LEFT

    @property
    def sign(self) -> float:
        """+1.0 for LEFT, -1.0 for RIGHT: lateral offset direction in a frame with x forward, y left."""
        return 1.0 if self is Side.LEFT else -1.0

    @classmethod
    def parse(cls, name: "str | Side") -> "Side":
        """`Side.LEFT` from "left"/"LEFT"/Side.LEFT; a ValueError naming the allowed values otherwise."""
        if isinstance(name, Side):
            return name
        if isinstance(name, enum.Enum):
            name = name.value
        if isinstance(name, str):
            key = name.strip().lower()
            for side in cls:
                if side.value == key:
                    return side
        raise ValueError(f"unknown side {name!r}; allowed: left, right")

    def __str__(self) -> str:
        return self.value
