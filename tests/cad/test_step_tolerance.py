"""Model-scaled tolerances (cadfeat.cad.tolerance): references are hand-written STEP headers (units and
uncertainty written out) and boxes of known size."""

from __future__ import annotations

import math

import pytest

from cadfeat.cad.tolerance import (
    ANGULAR_FLOOR_RAD,
    LINEAR_CAP_MM,
    LINEAR_FLOOR_MM,
    SIZE_RTOL,
    ModelTolerance,
    step_uncertainty_mm,
)

HEADER = """ISO-10303-21;
DATA;
#1=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT({prefix},.METRE.));
#2=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE({value}),#1,'DISTANCE_ACCURACY_VALUE','');
ENDSEC;
"""
INCH = """ISO-10303-21;
DATA;
#32=(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.CENTI.,.METRE.));
#34=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(2.54),#32);
#38=(CONVERSION_BASED_UNIT('INCH',#34)LENGTH_UNIT()NAMED_UNIT(#33));
#40=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(0.000393700787402),#38,'DISTANCE_ACCURACY_VALUE','');
ENDSEC;
"""


@pytest.mark.parametrize(("prefix", "value", "mm"), [(".MILLI.", "1.E-05", 1e-5), ("$", "1.E-06", 1e-3),
                                                      (".CENTI.", "0.001", 0.01)])
def test_step_uncertainty_is_converted_from_the_files_unit(tmp_path, prefix, value, mm):
    path = tmp_path / "u.step"
    path.write_text(HEADER.format(prefix=prefix, value=value))
    assert step_uncertainty_mm(path) == pytest.approx(mm, rel=1e-12)


def test_inch_uncertainty_in_mm_and_missing_uncertainty(tmp_path):
    inch, none = tmp_path / "inch.step", tmp_path / "none.step"
    inch.write_text(INCH)
    none.write_text("ISO-10303-21;\nDATA;\nENDSEC;\n")
    assert step_uncertainty_mm(inch) == pytest.approx(0.01, rel=1e-9)
    assert step_uncertainty_mm(none) is None


@pytest.mark.parametrize("size", [10.0, 6000.0])
def test_tolerance_grows_with_model_size_and_file_precision(size):
    import cadquery as cq

    box = cq.Solid.makeBox(size, size, size)
    diag = size * math.sqrt(3)
    tol = ModelTolerance.of_shape(box)
    assert tol.size_mm == pytest.approx(diag, rel=1e-6)
    assert tol.linear_mm == pytest.approx(max(LINEAR_FLOOR_MM, SIZE_RTOL * diag, tol.brep_tol_mm), rel=1e-12)
    assert tol.angular_rad == pytest.approx(max(ANGULAR_FLOOR_RAD, 2 * tol.linear_mm / diag), rel=1e-12)
    loose = ModelTolerance.of_shape(box, step_uncertainty=0.01)
    assert loose.linear_mm == pytest.approx(0.01) and ModelTolerance.of_shape(box, 1.0).linear_mm == LINEAR_CAP_MM
