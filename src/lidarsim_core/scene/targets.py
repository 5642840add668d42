"""Target models: meshes built in code, registered as plugins (``mesh: {model: NAME}``)."""

from __future__ import annotations

from abc import abstractmethod
from functools import lru_cache

from ..base.components import Component
from .mesh import Mesh


class TargetModel(Component):
    """A procedural target. Subclasses implement :meth:`build`; results are cached per options."""

    @abstractmethod
    def build(self) -> Mesh:
        """Build the mesh (body frame, metres, with part labels)."""

    def mesh(self) -> Mesh:
        """The mesh for these options, built once per process."""
        return _cached_build(type(self), self.options)


@lru_cache(maxsize=16)
def _cached_build(cls: type[TargetModel], options: object) -> Mesh:
    return cls(options).build()
