"""The default cell's numbers, each declared once (no imports: every layer may read them at no cost).

``cadfeat.cell.Cell``'s field defaults are these, and so are the defaults of the lower-level configurations that
take a cell's numbers (``vision.images.SensorModel``, ``vision.closed_loop.TrackingConfig``,
``measures.pose_models.PoseModels``, ``measures.pose_information``, ``design.uncertainty``): a study's ``[cell]``
replaces them all at once.
"""

HOLE_ENDS = ("as_modelled", "drilled", "milled")
"""How a blind hole ends as the shop makes it: as the CAD model has it, a 118° drill point, or a flat floor
(``cad.hole_ends``)."""
DETECTORS = ("cadfeat", "edcircles", "blob")
"""The closed loop's hole detectors (``vision.detectors``): cadfeat's own, EDCircles (OpenCV contrib, written
elsewhere) and SimpleBlobDetector (the naive practitioner's)."""
RENDERERS = ("raster", "pbr")
"""The closed loop's renderers (``render.interface``): VTK raster (holes painted dark) and Mitsuba 3 (physics)."""

CAMERA_POSITION_MM = 2.0
"""± the camera's mount position tolerance per axis (mm, camera frame)."""
CAMERA_ANGLE_DEG = 1.0
"""± the camera's mount angle tolerance per axis (deg)."""
PLACEMENT_POSITION_MM = 0.5
"""± the part's placement position tolerance per axis (mm, part frame)."""
PLACEMENT_ANGLE_DEG = 0.5
"""± the part's placement angle tolerance per axis (deg)."""
PLACEMENT_SIGMA_PER_TOLERANCE = 0.4
"""The placement error the closed loop draws per run and g_POSE's association term assumes: a normal of σ = 0.4 t
per axis, t the tolerance (±t is 2.5 σ: 98.8 % of the runs inside it)."""
NOISE_SIGMA_GREY = 2.0
"""σ of the sensor's grey-level noise (0..255 scale, per pixel and frame)."""
NOISE_SPREAD_GREY = 1.0
"""± that σ from cell to cell (the robust draws)."""
GAIN_SIGMA = 0.05
"""Relative σ of the light's gain from run to run."""
GATE_PX = 10.0
"""Association gate of a detection to its hole's predicted rim centre (px)."""
PLACEMENT_SIGMA_MM = PLACEMENT_SIGMA_PER_TOLERANCE * PLACEMENT_POSITION_MM
"""σ per axis of the default cell's placement translation (mm)."""
PLACEMENT_SIGMA_DEG = PLACEMENT_SIGMA_PER_TOLERANCE * PLACEMENT_ANGLE_DEG
"""σ per axis of the default cell's placement rotation (deg)."""
