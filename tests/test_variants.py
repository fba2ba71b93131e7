"""sengine.variants: seeds, map sets paired by stem, sweeps and manifests, and how they multiply into variants."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sengine.errors import ConfigError, InputDataError
from sengine.variants import (
    MAX_VARIANTS,
    pair_maps,
    parse_seeds,
    parse_sweeps,
    plan_variants,
    read_manifest,
)


# -- seeds ---------------------------------------------------------------------------------------------------------
def test_seeds_as_lists_and_ranges():
    assert parse_seeds("1-3,7, 9 - 10") == [1, 2, 3, 7, 9, 10]
    assert parse_seeds("0") == [0]


@given(st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 20)), min_size=1, max_size=6))
def test_seeds_parse_what_they_print(parts):
    """Disjoint ranges written as text come back as the numbers they hold, in order."""
    ranges, start = [], 0
    for gap, length in parts:
        a = start + gap
        ranges.append((a, a + length))
        start = a + length + 1
    text = ",".join(f"{a}-{b}" if b > a else str(a) for a, b in ranges)
    assert parse_seeds(text) == [s for a, b in ranges for s in range(a, b + 1)]


@pytest.mark.parametrize(
    "text, message",
    [
        ("5-1", "runs backwards"),
        ("1-1000000000", "at most 100,000"),
        ("0-99999,100000-100001", "at most 100,000"),
        ("x", "is not a seed"),
        ("-3", "is not a seed"),
        ("1,,2", "is not a seed"),
        ("1,2,1", "seed 1 is given twice"),
        ("1-3,2", "seed 2 is given twice"),
        ("9223372036854775808", "largest seed"),
    ],
)
def test_bad_seeds_are_one_line_errors(text, message):
    with pytest.raises(ConfigError, match=message) as err:
        parse_seeds(text)
    assert str(err.value).startswith("--seeds: ") and "\n" not in str(err.value)


# -- maps ----------------------------------------------------------------------------------------------------------
def _files(root, names):
    for name in names:
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"x")


def test_maps_pair_by_stem(tmp_path):
    _files(tmp_path, ["lu/b.png", "lu/a.png", "h/a.png", "h/b.png", "h/notes.txt"])
    sets = pair_maps(["landuse=lu/*.png", "height=h"], base_dir=tmp_path)  # a folder means its *.png
    assert [stem for stem, _ in sets] == ["a", "b"]
    for stem, maps in sets:
        assert [(k, p.rsplit("/", 2)[-2:]) for k, p, _ in maps] == [
            ("landuse", ["lu", f"{stem}.png"]),
            ("height", ["h", f"{stem}.png"]),
        ]


def test_a_stem_in_one_folder_only_is_named(tmp_path):
    _files(tmp_path, ["lu/a.png", "lu/extra.png", "h/a.png"])
    with pytest.raises(ConfigError, match="the stem 'extra' has a landuse map .* but no height map"):
        pair_maps(["landuse=lu/*.png", "height=h/*.png"], base_dir=tmp_path)


@pytest.mark.parametrize(
    "specs, message",
    [
        (["landuse=none/*.png"], "matches no file"),
        (["landuse"], "must be KIND=PATTERN"),
        (["=lu/*.png"], "must be KIND=PATTERN"),
        (["landuse=lu/*.png", "landuse=lu/*.png"], "given twice"),
        (["landuse=lu/*"], "two landuse maps have the stem 'a'"),
    ],
)
def test_bad_map_sets(tmp_path, specs, message):
    _files(tmp_path, ["lu/a.png", "lu/a.jpg"])
    with pytest.raises(ConfigError, match=message):
        pair_maps(specs, base_dir=tmp_path)


# -- sweeps --------------------------------------------------------------------------------------------------------
def test_one_value_sets_and_several_sweep():
    fixed, sweeps = parse_sweeps(["lots.depth=18", "roads.width=10, 12,14", "a.b=800 260"])
    assert fixed == ["lots.depth=18", "a.b=800 260"]
    assert sweeps == [("roads.width", ["10", "12", "14"])]


@pytest.mark.parametrize(
    "sets, message",
    [
        (["lots.depth=1,,2"], "empty value"),
        (["lots.depth=1,2,1"], "'1' twice"),
        (["lots=1,2"], "NODE.PARAM"),
        (["lots.depth=1", "lots.depth=2,3"], "set twice"),
    ],
)
def test_bad_sweeps(sets, message):
    with pytest.raises(ConfigError, match=message):
        parse_sweeps(sets)


# -- manifests -----------------------------------------------------------------------------------------------------
def test_manifest_rows(tmp_path):
    _files(tmp_path, ["maps/lu1.png", "maps/lu2.png"])
    m = tmp_path / "variants.csv"
    m.write_text(
        "id,seed,landuse,lots.depth\nnorth,3,maps/lu1.png,\n\n# a comment row\nsouth,4,maps/lu2.png,20\n,5,,30\n"
    )
    rows = read_manifest(m)
    assert [r.id for r in rows] == ["north", "south", None]
    assert [r.seed for r in rows] == [3, 4, 5]
    assert rows[0].maps[0][:2] == ("landuse", str(tmp_path / "maps" / "lu1.png"))
    assert rows[0].params == () and rows[1].params[0][:2] == ("lots.depth", "20")
    assert rows[1].where.endswith("variants.csv:5")  # the file's line, comments and blanks counted
    variants = plan_variants(config_seed=1, manifest=rows)
    assert [v.id for v in variants] == ["north", "south", "s5-lots.depth=30"]  # a row without id: from its values
    assert variants[2].inputs() == {"seed": 5, "maps": {}, "params": {"lots.depth": "30"}}


@pytest.mark.parametrize(
    "text, error, message",
    [
        (
            "id,seed,landuse\na,1,missing.png\n",
            InputDataError,
            r"variants.csv:2: column landuse: map file .* not found",
        ),
        ("id,seed\na,1\na,2\n", ConfigError, r"variants.csv:3: the variant id 'a' is also the id of .*variants.csv:2"),
        ("id,seed\nA,1\na,2\n", ConfigError, r"variants.csv:3: the variant id"),  # folders on macOS: one
        ("id,seed\na,x\n", ConfigError, r"variants.csv:2: seed 'x' is not a whole number"),
        ("id,seed\na,1,2\n", ConfigError, r"variants.csv:2: the row has 3 cells, the header 2"),
        ("id,seed\n", ConfigError, "header but no variant row"),
        ("", ConfigError, "the manifest is empty"),
        ("id,seed,seed\na,1,2\n", ConfigError, "the column 'seed' is given twice"),
        ("id,lots.\na,1\n", ConfigError, "is not NODE.PARAM"),
        ("id,my map\na,1\n", ConfigError, "not id, seed, NODE.PARAM or a map kind"),
        ("id\n../up\n", ConfigError, "may hold only letters"),
        ("id\n.hidden\n", ConfigError, "may hold only letters"),
    ],
)
def test_bad_manifests_name_file_and_line(tmp_path, text, error, message):
    m = tmp_path / "variants.csv"
    m.write_text(text)
    with pytest.raises(error, match=message):
        read_manifest(m)


def test_missing_manifest(tmp_path):
    with pytest.raises(InputDataError, match="manifest file not found"):
        read_manifest(tmp_path / "nope.csv")


# -- combining -----------------------------------------------------------------------------------------------------
def test_sources_multiply_with_readable_ids(tmp_path):
    _files(tmp_path, ["lu/paris.png", "lu/rome.png"])
    variants = plan_variants(
        config_seed=7,
        seeds=[1, 2],
        map_sets=pair_maps(["landuse=lu"], base_dir=tmp_path),
        sweeps=[("lots.depth", ["16", "18"])],
    )
    assert len(variants) == 2 * 2 * 2
    assert variants[0].id == "paris-s1-lots.depth=16" and variants[-1].id == "rome-s2-lots.depth=18"
    assert len({v.id for v in variants}) == 8
    assert variants[-1].inputs() == {
        "seed": 2,
        "maps": {"landuse": str(tmp_path / "lu" / "rome.png")},
        "params": {"lots.depth": "18"},
    }
    assert [v.id for v in plan_variants(config_seed=7)] == ["s7"]  # nothing varied: the config's seed
    assert plan_variants(config_seed=7)[0].seed is None


def test_one_thing_varied_twice_is_an_error(tmp_path):
    _files(tmp_path, ["lu/a.png"])
    m = tmp_path / "v.csv"
    m.write_text("id,seed,landuse,lots.depth\na,1,lu/a.png,3\n")
    rows = read_manifest(m)
    with pytest.raises(ConfigError, match="seed column and by --seeds"):
        plan_variants(config_seed=0, manifest=rows, seeds=[1, 2])
    with pytest.raises(ConfigError, match="landuse map is given by the manifest and by --maps"):
        plan_variants(config_seed=0, manifest=rows, map_sets=pair_maps(["landuse=lu"], base_dir=tmp_path))
    with pytest.raises(ConfigError, match="lots.depth is given by the manifest and by --set"):
        plan_variants(config_seed=0, manifest=rows, sweeps=[("lots.depth", ["1", "2"])])
    with pytest.raises(ConfigError, match="by --maps and by --map"):
        plan_variants(
            config_seed=0, map_sets=pair_maps(["landuse=lu"], base_dir=tmp_path), fixed_maps=("landuse=x.png",)
        )


def test_an_id_may_not_be_a_file_of_the_batch(tmp_path):
    m = tmp_path / "v.csv"
    m.write_text("id,seed\nbatch.csv,1\n")
    with pytest.raises(ConfigError, match="v.csv:2: the variant id 'batch.csv' is the name of a file the batch"):
        plan_variants(config_seed=0, manifest=read_manifest(m))


def test_too_many_variants_is_an_error_before_any_is_made():
    with pytest.raises(ConfigError, match=f"at most {MAX_VARIANTS:,}"):
        plan_variants(config_seed=0, seeds=list(range(1000)), sweeps=[("a.b", [str(i) for i in range(101)])])
