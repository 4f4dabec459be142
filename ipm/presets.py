"""The paper's 12 real yarns (supplemental tables "Inferred raw yarn parameters" and
"Inferred flyaway parameters").

Raw yarn values are the first row of each yarn (the parameter-specific networks), whose
thickness column is a class: 1 = thin (t_x 0.01, t_y 0.007), 2 = thick (0.018, 0.01); the
other rows of the same table show class 2 as the yarns with the larger t_x.  The flyaway
table's column headed ``m`` is the flyaway count ``g``.

The flyaway table names four yarns differently; we match them by ply count and appearance:

* ``light`` (2 plies) <- "light 2ply";  ``mixed`` (3 plies, the light mixed-fiber yarn of the
  paper's Fig. 12 top row) <- "light 3ply", the only other light yarn and the only 3-ply left;
* ``grey_thin`` <- "grey-blue" and ``grey_thick`` <- "grey": the two grey yarns, the bluish one
  being the thin one of Fig. 12.

``j_z`` is not in the tables: :data:`ipm.params.DEFAULT_J_Z`.  Colours are our estimate of
each yarn's name (linear RGB), since the paper did not infer appearance.
"""

from __future__ import annotations

from ipm.params import DEFAULT_J_Z, THICKNESS_CLASSES, YarnParams

# name: (n, alpha_ply, R_ply, alpha, r_x, r_y, m, thickness class)
_RAW = {
    "rose": (4, 4.515, 0.555, -3.611, 0.329, 0.283, 72, 2),
    "red": (4, 7.815, 0.449, -2.442, 0.297, 0.240, 131, 1),
    "golden": (3, 6.474, 0.289, -2.392, 0.241, 0.195, 43, 2),
    "pink_6ply": (6, 10.679, 0.672, -3.288, 0.390, 0.350, 64, 2),
    "mixed": (3, 14.961, 0.639, -6.152, 0.521, 0.423, 99, 2),
    "blue": (4, 11.009, 0.602, -2.866, 0.406, 0.298, 74, 1),
    "yellow": (4, 6.398, 0.393, -2.023, 0.278, 0.236, 65, 1),
    "grey_thin": (2, 3.348, 0.139, -1.175, 0.146, 0.115, 82, 1),
    "pink_4ply": (4, 5.605, 0.364, -2.419, 0.249, 0.230, 49, 2),
    "grey_thick": (2, 3.825, 0.254, -2.525, 0.334, 0.232, 148, 1),
    "orange": (4, 6.995, 0.440, -3.181, 0.309, 0.275, 52, 2),
    "light": (2, 10.705, 0.369, -3.654, 0.380, 0.318, 93, 2),
}
# flyaway-table name: (g, p, l_hair, beta, s, l_loop, d_mean, d_std, j_xy, j)
_FLY = {
    "red": (151, 0.48, 2.41, 0.86, 0.65, 4.75, 7.77, 2.35, 0.014, 0.20),
    "golden": (123, 0.50, 2.26, 0.77, 0.44, 4.48, 4.44, 2.08, 0.014, 0.19),
    "light 3ply": (160, 0.53, 4.71, 0.77, 0.55, 12.38, 11.10, 2.68, 0.019, 0.19),
    "orange": (163, 0.54, 3.50, 1.07, 0.46, 5.14, 7.83, 1.78, 0.015, 0.20),
    "rose": (147, 0.51, 2.61, 0.83, 0.49, 4.40, 8.30, 1.53, 0.014, 0.21),
    "grey-blue": (177, 0.44, 1.93, 0.97, 0.43, 4.03, 5.42, 1.70, 0.010, 0.16),
    "pink 4ply": (154, 0.56, 3.1, 0.82, 0.45, 4.66, 4.69, 2.35, 0.018, 0.23),
    "blue": (182, 0.45, 2.91, 0.85, 0.73, 7.20, 10.61, 1.68, 0.014, 0.19),
    "grey": (200, 0.42, 1.72, 0.85, 0.36, 3.22, 3.38, 1.52, 0.015, 0.17),
    "yellow": (183, 0.35, 1.78, 0.88, 0.52, 4.14, 7.79, 1.45, 0.011, 0.16),
    "pink 6ply": (175, 0.54, 3.70, 0.97, 0.62, 7.04, 10.74, 2.14, 0.016, 0.22),
    "light 2ply": (223, 0.47, 4.75, 1.12, 0.48, 8.14, 13.12, 2.08, 0.011, 0.23),
}
FLYAWAY_TABLE_NAME = {
    "rose": "rose", "red": "red", "golden": "golden", "pink_6ply": "pink 6ply",
    "mixed": "light 3ply", "blue": "blue", "yellow": "yellow", "grey_thin": "grey-blue",
    "pink_4ply": "pink 4ply", "grey_thick": "grey", "orange": "orange", "light": "light 2ply",
}
_COLOR = {
    "rose": (0.72, 0.36, 0.42), "red": (0.55, 0.04, 0.05), "golden": (0.75, 0.5, 0.14),
    "pink_6ply": (0.88, 0.45, 0.62), "mixed": (0.72, 0.66, 0.55), "blue": (0.08, 0.16, 0.5),
    "yellow": (0.85, 0.7, 0.08), "grey_thin": (0.38, 0.42, 0.5), "pink_4ply": (0.8, 0.35, 0.5),
    "grey_thick": (0.35, 0.35, 0.35), "orange": (0.88, 0.3, 0.04), "light": (0.82, 0.8, 0.72),
}
PRESET_NAMES: tuple[str, ...] = tuple(_RAW)


def preset(name: str) -> YarnParams:
    """One of the paper's 12 real yarns by name (see :data:`PRESET_NAMES`)."""
    if name not in _RAW:
        from ipm.errors import UserError

        raise UserError(f"unknown preset {name!r}; choose one of: {', '.join(PRESET_NAMES)}")
    n, alpha_ply, R_ply, alpha, r_x, r_y, m, cls = _RAW[name]
    g, p, l_hair, beta, s, l_loop, d_mean, d_std, j_xy, j = _FLY[FLYAWAY_TABLE_NAME[name]]
    t_x, t_y = THICKNESS_CLASSES["thin" if cls == 1 else "thick"]
    return YarnParams(n=n, m=m, t_x=t_x, t_y=t_y, alpha=alpha, r_x=r_x, r_y=r_y,
                      alpha_ply=alpha_ply, R_ply=R_ply, j=j, j_xy=j_xy, j_z=DEFAULT_J_Z, g=g,
                      p=p, beta=beta, l_hair=l_hair, s=s, l_loop=l_loop, d_mean=d_mean,
                      d_std=d_std, color=_COLOR[name])
