"""Bad image maps through the command line: one line naming the file, exit 2, no OUT."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS
from PIL import Image

from sengine.cli import main

MANHATTAN = CONFIGS / "manhattan.xml"


def _district_map_with_a_stray_colour(path):
    img = np.asarray(Image.open(CONFIGS / "maps" / "manhattan_districts.png").convert("RGB")).copy()
    img[100:110, 200:210] = (1, 254, 3)  # a 10 x 10 px patch of a colour no <district> names
    Image.fromarray(img).save(path)


@pytest.mark.parametrize(
    "kind, make, pattern",
    [
        ("landuse", lambda p: p.write_text("not an image"), r"manhattan_landuse_bad.png"),
        ("height", lambda p: Image.new("L", (50, 400), 128).save(p), r"50x400 px .* ratios must agree"),
        (
            "district",
            _district_map_with_a_stray_colour,
            r"colour #01fe03 at pixel \(x=200, y=100\) is not in the district rules",
        ),
        ("height", lambda p: None, r"does not exist|not found|missing"),
    ],
)
def test_bad_map_is_one_line_and_exit_2(kind, make, pattern, tmp_path, capsys):
    import re

    bad = tmp_path / f"manhattan_{kind}_bad.png"
    make(bad)
    out = tmp_path / "OUT"
    status = main(["run", str(MANHATTAN), "-o", str(out), "--quiet", "--map", f"{kind}={bad}"])
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1, err
    assert "Traceback" not in err and str(bad.name) in lines[0]
    assert re.search(pattern, lines[0], flags=re.I), lines[0]
    assert not out.exists()
