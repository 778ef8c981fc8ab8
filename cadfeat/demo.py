"""``make demo``: the flagship study (replaced by the real study runner once it exists)."""

from __future__ import annotations

from cadfeat.camera import Camera


def main() -> int:
    cam = Camera.preset("dalsa-cad1-128a")
    near, far = cam.depth_of_field_mm
    print(f"camera {cam.name}: depth of field {near:.1f}-{far:.1f} mm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
