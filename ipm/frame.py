"""The physical frame of the reference capture, shared by the generator and the scene.

The paper crops its macro photos to 2000x600 px with the yarn running horizontally through
the centre.  ``ipm`` fixes the size of one pixel at the yarn so that an image tells absolute
sizes: at ``PIXEL_SIZE_MM`` = 0.01 mm the full frame covers 20 x 6 mm, which holds the
thickest core of the value intervals (2 (R_ply + r_x) <= 4.6 mm) with room for flyaways, and
resolves the thinnest fibers of the intervals (2 t_y >= 0.012 mm) at about one pixel.
"""

FRAME_WIDTH_PX = 2000
FRAME_HEIGHT_PX = 600
PIXEL_SIZE_MM = 0.01
FRAME_WIDTH_MM = FRAME_WIDTH_PX * PIXEL_SIZE_MM
FRAME_HEIGHT_MM = FRAME_HEIGHT_PX * PIXEL_SIZE_MM


def pixel_size_mm(scale: float) -> float:
    """The pixel pitch (mm at the yarn) of the frame rendered at ``scale`` (1: the full
    2000 x 600 px).  The same division turns a pitch into its scale, so it is its own
    inverse: ``pixel_size_mm(pixel_size_mm(s)) == s``.

    >>> pixel_size_mm(0.25), pixel_size_mm(0.04)
    (0.04, 0.25)
    """
    return PIXEL_SIZE_MM / scale


def pitch_factor(pixel_size_mm: float, scale: float = 1.0) -> float:
    """How many scene pixels at ``scale`` one photo pixel of ``pixel_size_mm`` covers (> 1:
    the photo is upsampled to reach the scene's pitch)."""
    return pixel_size_mm * scale / PIXEL_SIZE_MM

#: Margin of a generated yarn beyond the view it is rendered in, both sides together: fiber
#: ends and small rotations of the yarn (photometric variation) stay out of view.
YARN_MARGIN_MM = 6.0
#: Length of a generated yarn along its axis: the frame's width plus the margin.
YARN_LENGTH_MM = FRAME_WIDTH_MM + YARN_MARGIN_MM


def view_yarn_length(width_mm: float, height_mm: float) -> float:
    """The length of yarn a view of ``width_mm`` x ``height_mm`` needs: its diagonal (the
    yarn at any tilt) plus :data:`YARN_MARGIN_MM`, at most :data:`YARN_LENGTH_MM`.  A search
    over a microscope's 3 mm field generates a third of the yarn frame's fibers."""
    return min(YARN_LENGTH_MM, (width_mm ** 2 + height_mm ** 2) ** 0.5 + YARN_MARGIN_MM)
