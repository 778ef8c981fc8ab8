"""Sub-command ``cadfeat detect IMAGES…``: the hole detectors on recorded images, without a study
(``cadfeat.vision.image_detection``).

Prints one line per image as it goes (the ellipses each detector found, or why the image was not detected) and a
summary; writes into ``--out`` (default ``detections/``) ``detections.csv`` (one row per ellipse:
``image_detection.CSV_COLUMNS``), ``detections.json`` (settings, summary, per image its size, counts and ellipses)
and, unless ``--no-pictures``, ``annotated/<image name>.png`` (the image with each detector's ellipses and their
CSV indices).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from cadfeat.cell.defaults import DETECTORS
from cadfeat.cli.command import Command
from cadfeat.errors import CadfeatError

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.vision.image_detection import ImageResult, Summary

ALL = "all"


def _detect_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("images", metavar="IMAGES", nargs="+", help="image files (PNG/JPEG/TIFF/PGM, 8 or 16 bit, "
                        "colour or grey) or folders of them")
    parser.add_argument("--detector", choices=(*DETECTORS, ALL), default="cadfeat",
                        help="cadfeat (threshold, sub-pixel edge, ellipse fit), edcircles (OpenCV contrib), blob "
                        "(SimpleBlobDetector) or all three (default cadfeat)")
    parser.add_argument("--holes", choices=("dark", "bright"), default="dark",
                        help="holes darker than the face around them (default), or brighter (backlit part, white "
                        "dots on a dark target: the image is inverted first)")
    parser.add_argument("--calibration", metavar="FILE", help="the camera's calibration (OpenCV or ROS YAML, e.g. "
                        "from cadfeat calibrate): cadfeat's centres of the undistorted rim; images of another size "
                        "are reported, not detected")
    parser.add_argument("--out", metavar="DIR", default="detections",
                        help="folder for detections.csv, detections.json and annotated/ (default detections/)")
    parser.add_argument("--no-pictures", action="store_true", help="do not write the annotated pictures")


def image_line(i: int, n: int, result: ImageResult) -> str:
    """The progress line of image ``i`` of ``n``: its name and the ellipses per detector, or its problem."""
    head = f"  [{i}/{n}] {result.path}"
    if result.problem is not None:
        return f"{head}: not detected: {result.problem}"
    counts = ", ".join(f"{name} {k}" for name, k in result.counts.items())
    w, h = result.size_px or (0, 0)
    return f"{head} ({w}x{h}): {counts} ellipse(s)"


def picture_names(results: list[ImageResult]) -> list[str]:
    """``<stem>.png`` per image, ``<stem>_2.png``… where two images share a stem."""
    seen: dict[str, int] = {}
    names = []
    for r in results:
        stem = r.path.stem
        seen[stem] = seen.get(stem, 0) + 1
        names.append(f"{stem}.png" if seen[stem] == 1 else f"{stem}_{seen[stem]}.png")
    return names


def _write_outputs(results: list[ImageResult], detectors: list[str], args: argparse.Namespace) -> list[Path]:
    """detections.csv, detections.json and the annotated pictures; the paths written."""
    import cv2

    from cadfeat.study.outputs import write_json  # lazy: keeps `cadfeat --help` fast
    from cadfeat.vision.image_detection import CSV_COLUMNS, annotated, csv_rows, to_json
    from cadfeat.vision.image_files import read_grey

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    table = out / "detections.csv"
    with table.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=CSV_COLUMNS, lineterminator="\n")
        writer.writeheader()
        for row in csv_rows(results):
            writer.writerow({k: ("" if v is None else f"{v:.4f}" if isinstance(v, float) else v)
                             for k, v in row.items()})
    written = [table, write_json(out / "detections.json", to_json(results, detectors, args.holes,
                                                                 args.calibration))]
    if not args.no_pictures:
        folder = out / "annotated"
        folder.mkdir(exist_ok=True)
        for r, name in zip(results, picture_names(results), strict=True):
            if r.problem is None:
                path = folder / name
                if not cv2.imwrite(str(path), annotated(read_grey(r.path), r.found)):
                    raise CadfeatError(f"{path}: could not be written")
        written.append(folder)
    return written


def summary_lines(section: Summary) -> list[str]:
    """Console summary of ``image_detection.summary``: per detector the ellipses found and their spread."""
    lines = [f"detect: {section['images_detected']} of {section['images']} images detected"]
    for name, s in section["detectors"].items():
        per = s["per_image"]
        spread = f"; per image {per['min']}-{per['max']} (median {per['median']:g})" if per else ""
        lines.append(f"  {name}: {s['ellipses']} ellipses in {s['images_with_ellipses']} images{spread}")
    lines += [f"  not detected: {p['image']}: {p['problem']}" for p in section["not_detected"]]
    return lines


def detect_images(args: argparse.Namespace) -> int:
    """Find holes (ellipses) in recorded images, without a study: centres, axes and angles per image."""
    from cadfeat.vision.image_detection import detect_files, summary
    from cadfeat.vision.image_files import expand_image_paths

    detectors = list(DETECTORS) if args.detector == ALL else [args.detector]
    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise CadfeatError(f"--out: {args.out} is a file; allowed: a folder (made if missing)")
    camera = None
    if args.calibration:
        from cadfeat.camera import Camera

        camera = Camera.from_opencv_file(args.calibration)
    paths = expand_image_paths(args.images)
    if not paths:
        raise CadfeatError(f"IMAGES: no image files in {', '.join(args.images)}; allowed: PNG, JPEG, TIFF or PGM "
                           "files, or folders of them")
    print(f"detect: {len(paths)} image(s), detector {', '.join(detectors)}, {args.holes} holes"
          + (f", calibration {args.calibration}" if args.calibration else ""), flush=True)

    def progress(i: int, n: int, result: ImageResult) -> None:
        print(image_line(i, n, result), flush=True)

    results = detect_files(paths, detectors, args.holes, camera, progress)
    section = summary(results, detectors)
    if not section["images_detected"]:
        raise CadfeatError("no image could be detected: " + "; ".join(
            f"{p['image']}: {p['problem']}" for p in section["not_detected"]))
    written = _write_outputs(results, detectors, args)
    print("\n".join(summary_lines(section)))
    print(f"  outputs: {', '.join(map(str, written))}")
    sys.stdout.flush()
    return 0


COMMANDS = (Command("detect", _detect_args, detect_images),)
