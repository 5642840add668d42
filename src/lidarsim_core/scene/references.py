"""The files a mesh file names (an OBJ's ``mtllib``, a material's textures, a glTF's buffer
and image URIs), read through the same bounded reader as the mesh itself.

trimesh reads referenced files through a *resolver*; its own one opens any path the file
names, so an ``mtllib`` naming a FIFO blocks forever, ``/dev/zero`` reads without end, and
``../../secret`` or ``/etc/passwd`` reach outside the model's folder. :class:`BoundedResolver`
accepts only relative paths inside the mesh's folder (no ``..``, no absolute path, no URI
scheme, no symbolic link out), and reads each through
:func:`~lidarsim_core.base.config_io.read_bytes_file` (regular files only, under the
``data_bytes`` limit). trimesh swallows a resolver's errors for materials and textures (it
loads the geometry without them), so every refusal is also kept in :attr:`refused` and the
mesh loader reports the first one.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any
from urllib.parse import unquote

from trimesh.resolvers import Resolver

from ..base.config_io import read_bytes_file
from ..base.errors import MeshError

_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


class BoundedResolver(Resolver):
    """Referenced files of the mesh ``path``: relative, inside its folder, bounded reads.

    Parameters
    ----------
    path
        The mesh file.
    source
        How the mesh is named in messages.
    """

    def __init__(self, path: str | Path, source: str | None = None) -> None:
        self.mesh = Path(path)
        self.parent = self.mesh.parent if str(self.mesh.parent) else Path(".")
        self.source = source or str(self.mesh)
        #: Every referenced file refused, with its reason (the first one is reported).
        self.refused: list[str] = []

    def _refuse(self, message: str) -> MeshError:
        self.refused.append(message)
        return MeshError(message, source=self.source)

    def resolve(self, name: str) -> Path:
        """The file ``name`` (as written in the mesh) refers to, refused unless it is a
        relative path inside the mesh's folder."""
        text = unquote(str(name)).strip()
        if not text or "\0" in text:
            raise self._refuse(f"references an empty or invalid file name {name!r}")
        if _SCHEME.match(text) and not re.match(r"^[A-Za-z]:[\\/]", text):
            raise self._refuse(f"references '{name}', a URI: only files beside the mesh "
                               "are read")
        relative = Path(text.replace("\\", "/"))
        if relative.is_absolute() or ".." in relative.parts or re.match(r"^[A-Za-z]:", text):
            raise self._refuse(f"references '{name}', outside the mesh's folder (absolute "
                               "paths and '..' are refused)")
        path = self.parent / relative
        try:
            inside = os.path.realpath(path)
            base = os.path.realpath(self.parent)
        except (OSError, ValueError) as exc:
            raise self._refuse(f"references '{name}', which cannot be resolved ({exc})"
                               ) from None
        if os.path.commonpath([inside, base]) != base:
            raise self._refuse(f"references '{name}', a symbolic link out of the mesh's "
                               "folder")
        return path

    def get(self, key: str) -> bytes:
        """The bytes of referenced file ``key`` (bounded; FIFOs, devices, directories and
        files over the limit refused)."""
        path = self.resolve(key)
        if not os.path.lexists(path):  # a missing material: loaded without it, as before
            raise FileNotFoundError(f"{path} not found")
        try:
            return read_bytes_file(path, "file referenced by the mesh",
                                   limit_name="data_bytes", error=MeshError,
                                   source=self.source, field=str(key))
        except MeshError as exc:
            self.refused.append(exc.message)
            raise

    def write(self, name: str, data: Any) -> None:
        """Never used when loading; lidarsim does not write through a resolver."""
        raise MeshError("a mesh loader tried to write a file", source=self.source)

    def namespaced(self, namespace: str) -> "BoundedResolver":
        """The resolver of a sub-folder (still bounded by the mesh's folder)."""
        sub = BoundedResolver(self.mesh, self.source)
        sub.parent = self.resolve(namespace)
        sub.refused = self.refused
        return sub

    def keys(self) -> Any:
        """Nothing is listed: files are read only when the mesh names them."""
        return iter(())
