"""``render_mode="rgb_array"``: the x–y projection of the particles with the field arrow."""

from __future__ import annotations

import numpy as np


def render_projection(
    positions: np.ndarray,
    box_length: float,
    direction: np.ndarray,
    amplitude: float,
    title: str = "",
    size_pixels: int = 320,
) -> np.ndarray:
    """RGB image (H, W, 3) uint8 of the particles projected on the flow–gradient (x–y) plane.

    Args:
        positions: (N, 3) wrapped centres (units a); disks of radius a, shaded by z.
        box_length: box side L (units a).
        direction: (3,) field direction; its x–y projection is drawn as an arrow from the box centre.
        amplitude: ``E0 / E0_max`` in [0, 1] (arrow length; no arrow when 0).
        title: figure title.
        size_pixels: width and height of the image.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    dpi = 80
    figure = Figure(figsize=(size_pixels / dpi, size_pixels / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(figure)
    axes = figure.add_axes((0.02, 0.02, 0.96, 0.9))
    shade = positions[:, 2] / box_length
    for (x, y), s in zip(positions[:, :2], shade, strict=True):
        axes.add_patch(
            Circle((x, y), 1.0, facecolor=(0.2 + 0.6 * s, 0.4, 0.9 - 0.6 * s), edgecolor="k", lw=0.3)
        )
    if amplitude > 0.0:
        centre = 0.5 * box_length
        length = 0.45 * box_length * min(1.0, amplitude)
        axes.annotate(
            "",
            xy=(centre + length * direction[0], centre + length * direction[1]),
            xytext=(centre - length * direction[0], centre - length * direction[1]),
            arrowprops={"arrowstyle": "<->", "color": "crimson", "lw": 2.5},
        )
    axes.set_xlim(0.0, box_length)
    axes.set_ylim(0.0, box_length)
    axes.set_aspect("equal")
    axes.set_xticks([])
    axes.set_yticks([])
    figure.suptitle(title, fontsize=8)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[:, :, :3]
    return np.ascontiguousarray(image)
