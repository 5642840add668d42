"""Off-screen 3-D rendering with pyvista: finding an OpenGL that works, and writing PNGs.

VTK (≥ 9.4) wheels pick their OpenGL window at run time: X11 when a display exists, else EGL,
else OSMesa. A missing library can crash the process (OSMesa without ``libOSMesa`` segfaults),
so :func:`rendering_backend` first renders a tiny scene in a child process, once per process,
trying the windows in turn; the one that worked is then selected for this process through VTK's
``VTK_DEFAULT_OPENGL_WINDOW`` variable. On Debian, EGL needs ``libegl1`` and ``libgl1-mesa-dri``
(software rendering through Mesa's llvmpipe, no GPU or display needed); OSMesa needs
``libosmesa6``.
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..base.atomic import atomic_output
from ..base.errors import LidarsimError

#: VTK's variable naming the OpenGL render-window class it should create.
WINDOW_VARIABLE = "VTK_DEFAULT_OPENGL_WINDOW"
#: What to install when no OpenGL renders here (said in messages and the docs).
OPENGL_HINT = ("3-D figures need an OpenGL that renders off-screen: on Debian/Ubuntu "
               "'apt-get install libegl1 libgl1-mesa-dri' (EGL) or 'libosmesa6' (OSMesa)")

# Renders a red sphere with bare VTK (importing pyvista would double the probe's time).
_PROBE = """
import sys
import vtkmodules.vtkRenderingOpenGL2
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkFiltersSources import vtkSphereSource
from vtkmodules.vtkRenderingCore import (vtkActor, vtkPolyDataMapper, vtkRenderer,
                                         vtkRenderWindow, vtkWindowToImageFilter)
source = vtkSphereSource()
mapper = vtkPolyDataMapper()
mapper.SetInputConnection(source.GetOutputPort())
actor = vtkActor()
actor.SetMapper(mapper)
actor.GetProperty().SetColor(1, 0, 0)
renderer = vtkRenderer()
renderer.AddActor(actor)
renderer.SetBackground(1, 1, 1)
window = vtkRenderWindow()
window.SetOffScreenRendering(1)
window.AddRenderer(renderer)
window.SetSize(64, 48)
window.Render()
grab = vtkWindowToImageFilter()
grab.SetInput(window)
grab.Update()
image = vtk_to_numpy(grab.GetOutput().GetPointData().GetScalars())
sys.exit(0 if image.std() > 1.0 else 3)
"""

_chosen: dict[str, Any] = {}


class RenderingUnavailable(LidarsimError):
    """No OpenGL window class could render off-screen on this machine."""


def _candidates() -> list[str | None]:
    """Render-window classes to try, best first (``None`` = VTK's own default)."""
    if os.environ.get(WINDOW_VARIABLE):
        return [os.environ[WINDOW_VARIABLE]]
    if not sys.platform.startswith("linux"):
        return [None]
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return [None, "vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow"]
    # no display: going straight to EGL avoids VTK's "bad X server connection" warning
    return ["vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow", None]


def _probe(window: str | None) -> bool:
    env = dict(os.environ)
    if window:
        env[WINDOW_VARIABLE] = window
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                              timeout=120)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def rendering_backend() -> str:
    """Select an off-screen OpenGL window class that renders here, and return its name.

    The result is cached for the process. Import pyvista only after calling this.

    Returns
    -------
    str
        The VTK render-window class chosen, or ``"default"`` for VTK's own choice.

    Raises
    ------
    RenderingUnavailable
        When pyvista is missing or no window class renders (see :data:`OPENGL_HINT`).
    """
    if "window" in _chosen:
        if _chosen["window"] is False:
            raise RenderingUnavailable(_chosen["why"])
        return _chosen["window"] or "default"
    from importlib.util import find_spec

    # not imported here: VTK must see the chosen window class before it first loads
    if find_spec("pyvista") is None or find_spec("vtkmodules") is None:
        _chosen.update(window=False, why="pyvista is not installed (pip install "
                                         "'lidarsim-core[viz]')")
        raise RenderingUnavailable(_chosen["why"])
    for window in _candidates():
        if _probe(window):
            if window:
                os.environ[WINDOW_VARIABLE] = window
            _chosen["window"] = window
            return window or "default"
    _chosen.update(window=False, why=f"no OpenGL renders off-screen here; {OPENGL_HINT}")
    raise RenderingUnavailable(_chosen["why"])


def new_plotter(shape: tuple[int, int] = (1, 1), window_size: tuple[int, int] = (1400, 900),
                **kwargs: Any) -> Any:
    """An off-screen ``pyvista.Plotter`` with a white background and anti-aliasing.

    Call :func:`rendering_backend` first (it raises when nothing can render).
    """
    import pyvista as pv

    pv.OFF_SCREEN = True
    plotter = pv.Plotter(off_screen=True, shape=shape, window_size=list(window_size),
                         border=False, **kwargs)
    plotter.set_background("white")
    try:
        plotter.enable_anti_aliasing("ssaa")
    except Exception:  # anti-aliasing is cosmetic; some OpenGLs lack the extension
        pass
    return plotter


def write_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an (H, W, 3|4) uint8 image to ``path`` as PNG, atomically."""
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(image)).save(buffer, format="PNG")
    with atomic_output(path) as stream:
        stream.write(buffer.getvalue())
    return Path(path)


def save_plotter(plotter: Any, path: str | Path) -> Path:
    """Render ``plotter`` to a PNG at ``path`` (atomic write) and close it."""
    try:
        image = plotter.screenshot(return_img=True)
    finally:
        plotter.close()
    if image is None or np.asarray(image).std() < 1.0:
        raise RenderingUnavailable(f"the renderer produced a blank image for {Path(path).name}; "
                                   f"{OPENGL_HINT}")
    return write_png(np.asarray(image), path)


def save_figure(figure: Any, path: str | Path, dpi: int = 150) -> Path:
    """Write a matplotlib ``Figure`` to a PNG at ``path`` (atomic write)."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi, facecolor="white")
    with atomic_output(path) as stream:
        stream.write(buffer.getvalue())
    return Path(path)
