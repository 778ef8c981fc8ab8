"""Four Ø8 mm through holes in a 100 x 80 x 5 mm plate, spread ±s by ±0.75 s (the closed-loop study tests:
``tests/vision/test_vision_study.py``, ``tests/vision/test_replay.py``)."""

PARAMETERS = {"spread_mm": {"default": 8.0, "bounds": (6.0, 38.0), "unit": "mm",
                             "description": "half spread"}}


def build(spread_mm=8.0):
    import cadquery as cq

    s = spread_mm
    pts = [(-s, -0.75 * s), (s, -0.75 * s), (s, 0.75 * s), (-s, 0.75 * s)]
    return cq.Workplane("XY").box(100, 80, 5).faces(">Z").workplane().pushPoints(pts).hole(8)
