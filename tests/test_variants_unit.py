"""Unit tests of :mod:`sengine.variants` (written for its mutation score, docs/mutation.md): exact messages and ids."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from sengine.errors import ConfigError, InputDataError
from sengine.variants import (
    MAX_SEED,
    MAX_VARIANTS,
    Variant,
    _Row,
    _row_id,
    _slug,
    pair_maps,
    parse_seeds,
    parse_sweeps,
    plan_variants,
    read_manifest,
)


def _raises(exc, text, call, *args, **kw):
    """``call`` raises ``exc`` whose message is exactly ``text``."""
    with pytest.raises(exc) as info:
        call(*args, **kw)
    assert str(info.value) == text
    return info.value


def _touch(root: Path, *names: str) -> None:
    for name in names:
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"x")


# -- seeds --------------------------------------------------------------------------------------------------------
def test_seed_messages_are_exact():
    _raises(
        ConfigError, "--seeds: '1,x': 'x' is not a seed (a whole number >= 0) or a range like 1-10", parse_seeds, "1,x"
    )
    _raises(ConfigError, "--seeds: '5-1': the range 5-1 runs backwards (write 1-5)", parse_seeds, "5-1")
    _raises(ConfigError, "m.csv:3: '2, 2': seed 2 is given twice", parse_seeds, "2, 2", where="m.csv:3")
    big = str(MAX_SEED + 1)
    _raises(ConfigError, f"--seeds: {big!r}: seed {big} is above the largest seed, 2**63 - 1", parse_seeds, big)
    assert parse_seeds(str(MAX_SEED)) == [MAX_SEED]
    _raises(
        ConfigError,
        "--seeds: '1-5,10-100005' gives 100,001 seeds or more; a batch makes at most 100,000 cities",
        parse_seeds,
        "1-5,10-100005",
    )


def test_seed_counts_at_the_limit():
    assert len(parse_seeds(f"1-{MAX_VARIANTS}")) == MAX_VARIANTS
    assert parse_seeds(" 4 - 6 ,8") == [4, 5, 6, 8] and parse_seeds("3-3") == [3]
    with pytest.raises(ConfigError, match="100,001 seeds"):
        parse_seeds(f"0-{MAX_VARIANTS}")
    with pytest.raises(ConfigError, match="'7' twice|seed 7 is given twice"):
        parse_seeds("5-9,7")


# -- maps ---------------------------------------------------------------------------------------------------------
def test_map_messages_are_exact(tmp_path):
    _touch(tmp_path, "lu/a.png", "lu/b.png", "h/a.png", "x/a.png", "x/a.jpg")
    _raises(ConfigError, "--maps landuse: must be KIND=PATTERN, e.g. landuse=maps/lu/*.png", pair_maps, ["landuse"])
    _raises(ConfigError, "--maps 1x=lu: must be KIND=PATTERN, e.g. landuse=maps/lu/*.png", pair_maps, ["1x=lu"])
    _raises(ConfigError, "--maps lu=: must be KIND=PATTERN, e.g. landuse=maps/lu/*.png", pair_maps, ["lu="])
    _raises(
        ConfigError,
        "--maps landuse=h: the map kind 'landuse' is given twice (also lu)",
        pair_maps,
        ["landuse=lu", "landuse=h"],
        base_dir=tmp_path,
    )
    _raises(ConfigError, "--maps landuse=none: 'none' matches no file", pair_maps, ["landuse=none"], base_dir=tmp_path)
    err = _raises(
        ConfigError,
        f"--maps: the stem 'b' has a landuse map ({(tmp_path / 'lu' / 'b.png').resolve()}) but no height map "
        "in 'h': every kind needs a file of each stem",
        pair_maps,
        [" landuse = lu ", "height=h"],
        base_dir=tmp_path,
    )
    assert err.where == "--maps"
    x = (tmp_path / "x").resolve()
    _raises(
        ConfigError,
        f"--maps d=x/*: two d maps have the stem 'a': {x / 'a.jpg'} and {x / 'a.png'}",
        pair_maps,
        ["d=x/*"],
        base_dir=tmp_path,
    )
    assert pair_maps([]) == []


def test_maps_pair_by_stem_with_where_and_absolute_patterns(tmp_path, monkeypatch):
    _touch(tmp_path, "lu/b.png", "lu/a.png", "h/a.png", "h/b.png", "h/sub.png/c.png")
    lu = (tmp_path / "lu").resolve()
    sets = pair_maps([f"landuse={lu}/*.png", f"height={tmp_path / 'h'}"], base_dir=tmp_path / "elsewhere")
    assert [s for s, _ in sets] == ["a", "b"]
    assert sets[0][1][0] == ("landuse", str(lu / "a.png"), f"--maps landuse={lu}/*.png")
    assert sets[1][1][1] == ("height", str((tmp_path / "h" / "b.png").resolve()), f"--maps height={tmp_path / 'h'}")
    monkeypatch.chdir(tmp_path)  # relative to the working folder without base_dir
    assert [s for s, _ in pair_maps(["landuse=lu"])] == ["a", "b"]


# -- sweeps -------------------------------------------------------------------------------------------------------
def test_sweep_messages_are_exact():
    _raises(ConfigError, "--set 'lots=1' must be NODE.PARAM=VALUE or NODE.PARAM=v1,v2,v3", parse_sweeps, ["lots=1"])
    _raises(ConfigError, "--set 'a.b' must be NODE.PARAM=VALUE or NODE.PARAM=v1,v2,v3", parse_sweeps, ["a.b"])
    _raises(ConfigError, "--set a.b: the parameter is set twice", parse_sweeps, ["a.b=1", " a.b =2"])
    _raises(ConfigError, "--set a.b: '1, ,2' has an empty value in its list", parse_sweeps, ["a.b=1, ,2"])
    _raises(ConfigError, "--set a.b: '1,2,3,2' gives the value '2' twice", parse_sweeps, ["a.b=1,2,3,2"])
    assert parse_sweeps([" a.b = 1 , 2", "c.d= x "]) == (["c.d= x "], [("a.b", ["1", "2"])])
    assert parse_sweeps([]) == ([], [])


# -- manifests ----------------------------------------------------------------------------------------------------
def test_manifest_messages_name_file_and_line(tmp_path):
    m = tmp_path / "v.csv"
    cases = [
        ("id,,seed\n", "v.csv:1: column 2 of the header has no name"),
        ("\n# note\nid,seed,id\n", "v.csv:3: the column 'id' is given twice"),
        ("id,a.b.c\n", "v.csv:1: the column 'a.b.c' is not NODE.PARAM"),
        ("id,2d\n", "v.csv:1: the column '2d' is not id, seed, NODE.PARAM or a map kind (a word)"),
        ("id,seed\na\n", "v.csv:2: the row has 1 cells, the header 2"),
        ("id\n-a\n", "v.csv:2: id '-a' may hold only letters, digits and . _ = + - (starting with a letter or digit)"),
        ("seed\n-1\n", "v.csv:2: seed '-1' is not a whole number from 0 to 2**63 - 1"),
        (f"seed\n{MAX_SEED + 1}\n", f"v.csv:2: seed '{MAX_SEED + 1}' is not a whole number from 0 to 2**63 - 1"),
        ("id,seed\nx,1\n\nX,2\n", "v.csv:4: the variant id 'X' is also the id of v.csv:2"),
        ("seed,a.b\n1,2\n1,2\n", "v.csv:3: the variant id 's1-a.b=2' is also the id of v.csv:2"),
        ("# only a comment\n\n", "v.csv: the manifest is empty (it needs a header row: id,seed,landuse,...)"),
        ("id,seed\n#a,1\n", "v.csv: the manifest has a header but no variant row"),
    ]
    for text, message in cases:
        m.write_text(text)
        with pytest.raises(ConfigError) as info:
            read_manifest(m)
        assert str(info.value) == message.replace("v.csv", str(m)), text
    m.write_text("id,landuse\na,nope.png\n")
    _raises(InputDataError, f"{m}:2: column landuse: map file 'nope.png' not found", read_manifest, m)
    _raises(InputDataError, f"{tmp_path / 'none.csv'}: manifest file not found", read_manifest, tmp_path / "none.csv")
    (tmp_path / "dir.csv").mkdir()
    with pytest.raises(InputDataError, match=f"^{re.escape(str(tmp_path / 'dir.csv'))}: cannot read the manifest: "):
        read_manifest(tmp_path / "dir.csv")
    m.write_bytes(b"id\n\xff\xfe\n")
    with pytest.raises(InputDataError, match="cannot read the manifest"):
        read_manifest(m)


def test_manifest_rows_hold_what_the_cells_say(tmp_path):
    _touch(tmp_path, "lu/a.png", "abs.png")
    m = tmp_path / "sub" / "v.csv"
    m.parent.mkdir()
    m.write_text(
        "\ufeffid , seed, landuse ,lots.depth, height\n"
        f" a , 3 , ../lu/a.png , 18 , {tmp_path / 'abs.png'}\n"
        ",,,,\n"
        ",0,,,\n"
    )
    rows = read_manifest(m)
    assert len(rows) == 2
    a, b = rows
    assert a == _Row(
        "a",
        3,
        (
            ("landuse", str((tmp_path / "lu" / "a.png").resolve()), f"{m}:2: column landuse"),
            ("height", str((tmp_path / "abs.png").resolve()), f"{m}:2: column height"),
        ),
        (("lots.depth", "18", f"{m}:2: column lots.depth"),),
        f"{m}:2",
    )
    assert b == _Row(None, 0, (), (), f"{m}:4") and _row_id(b) == "s0"


def test_row_ids_and_slugs():
    assert _slug("lots.depth=18") == "lots.depth=18"
    assert _slug("a b/c") == "a_b_c" and _slug("..x..") == "x" and _slug("__a__") == "a"
    assert _slug("///") == "_" and _slug("") == "_" and _slug("é") == "_"
    row = _Row(None, 7, (("landuse", "/m/north side.png", "w"),), (("a.b", "1 2", "w"),), "v.csv:9")
    assert _row_id(row) == "north_side-s7-a.b=1_2"
    assert _row_id(_Row(None, None, (), (), "v.csv:9")) == "r9"
    assert _row_id(_Row("given", 1, (), (), "v.csv:9")) == "given"


# -- plan_variants ------------------------------------------------------------------------------------------------
def test_variants_nest_manifest_maps_seeds_sweeps(tmp_path):
    _touch(tmp_path, "lu/p.png", "lu/q r.png", "m/x.png")
    m = tmp_path / "v.csv"
    m.write_text("id,height\none,m/x.png\ntwo,\n")
    rows = read_manifest(m)
    maps = pair_maps(["landuse=lu"], base_dir=tmp_path)
    vs = plan_variants(config_seed=9, seeds=[4], map_sets=maps, sweeps=[("a.b", ["1", "2"])], manifest=rows)
    assert [v.id for v in vs] == [
        "one-p-s4-a.b=1",
        "one-p-s4-a.b=2",
        "one-q_r-s4-a.b=1",
        "one-q_r-s4-a.b=2",
        "two-p-s4-a.b=1",
        "two-p-s4-a.b=2",
        "two-q_r-s4-a.b=1",
        "two-q_r-s4-a.b=2",
    ]
    v = vs[0]
    assert v.seed == 4 and v.where == f"{m}:2"
    assert [k for k, _, _ in v.maps] == ["height", "landuse"]
    assert v.params == (("a.b", "1", "--set a.b"),)
    plain = plan_variants(config_seed=9, seeds=[4, 5], map_sets=maps, sweeps=[("a.b", ["1"]), ("c.d", ["x", "y"])])
    assert plain[0].where == "--maps stem p, --seeds 4, --set a.b=1, --set c.d=x"
    assert plain[0].id == "p-s4-a.b=1-c.d=x" and len(plain) == 2 * 2 * 2
    only = plan_variants(config_seed=9, sweeps=[("a.b", ["1", "2"])])
    assert [(v.id, v.seed, v.where) for v in only] == [("a.b=1", None, "--set a.b=1"), ("a.b=2", None, "--set a.b=2")]
    seeds = plan_variants(config_seed=9, seeds=[0])
    assert [(v.id, v.seed, v.where, v.maps, v.params) for v in seeds] == [("s0", 0, "--seeds 0", (), ())]
    assert plan_variants(config_seed=3, seeds=[], map_sets=[], sweeps=[], manifest=[]) == [Variant("s3")]
    m.write_text("seed\n5\n")
    assert [(v.id, v.seed) for v in plan_variants(config_seed=3, manifest=read_manifest(m))] == [("s5", 5)]


def test_variant_conflicts_are_exact(tmp_path):
    _touch(tmp_path, "lu/a.png")
    m = tmp_path / "v.csv"
    m.write_text("id,seed,landuse,lots.depth\na,1,lu/a.png,3\n")
    rows = read_manifest(m)
    maps = pair_maps(["landuse=lu"], base_dir=tmp_path)
    w = f"{m}:2"
    _raises(
        ConfigError,
        f"{w}: the seed is given by the manifest's seed column and by --seeds",
        plan_variants,
        config_seed=0,
        manifest=rows,
        seeds=[1],
    )
    assert plan_variants(config_seed=0, manifest=rows, seeds=[]) != []
    _raises(
        ConfigError,
        f"{w}: column landuse: the landuse map is given by the manifest and by --maps",
        plan_variants,
        config_seed=0,
        manifest=rows,
        map_sets=maps,
    )
    _raises(
        ConfigError,
        f"{w}: column landuse: the landuse map is given by the manifest and by --map",
        plan_variants,
        config_seed=0,
        manifest=rows,
        fixed_maps=("landuse=x.png",),
    )
    for given in ({"sweeps": [("lots.depth", ["1", "2"])]}, {"fixed_sets": (" lots.depth =4",)}):
        _raises(
            ConfigError,
            f"{w}: column lots.depth: lots.depth is given by the manifest and by --set",
            plan_variants,
            config_seed=0,
            manifest=rows,
            **given,
        )
    _raises(
        ConfigError,
        "--maps: the landuse map is given by --maps and by --map",
        plan_variants,
        config_seed=0,
        map_sets=maps,
        fixed_maps=("landuse=x.png", "height=y.png"),
    )
    ok = plan_variants(config_seed=0, map_sets=maps, fixed_maps=("height=y.png",), fixed_sets=("a.b=1",))
    assert [v.id for v in ok] == ["a"]


def test_reserved_and_repeated_ids(tmp_path):
    m = tmp_path / "v.csv"
    for name in ("Contact.PNG", "batch.parquet"):
        m.write_text(f"id\n{name}\n")
        _raises(
            ConfigError,
            f"{m}:2: the variant id {name!r} is the name of a file the batch writes",
            plan_variants,
            config_seed=0,
            manifest=read_manifest(m),
        )
    _touch(tmp_path, "a/batch.csv", "b/batch.csv")
    _raises(
        ConfigError,
        "--maps stem batch.csv: the variant id 'batch.csv' is the name of a file the batch writes",
        plan_variants,
        config_seed=0,
        map_sets=[("batch.csv", ())],
    )
    _raises(
        ConfigError,
        "two variants have the id 'X-a.b=1' (also --maps stem x, --set a.b=1): give the manifest an id column",
        plan_variants,
        config_seed=0,
        map_sets=[("x", ()), ("X", ())],
        sweeps=[("a.b", ["1"])],
    )
    _raises(
        ConfigError,
        "two variants have the id 'r' (also the configuration): give the manifest an id column",
        plan_variants,
        config_seed=1,
        manifest=[_Row(None, None, (), (), ""), _Row(None, None, (), (), "")],
    )


def test_repeated_seeds_make_repeated_ids():
    _raises(
        ConfigError,
        "two variants have the id 's1' (also --seeds 1): give the manifest an id column",
        plan_variants,
        config_seed=0,
        seeds=[1, 1],
    )


def test_the_variant_limit_counts_every_source():
    sweeps = [("a.b", [str(i) for i in range(100)]), ("c.d", [str(i) for i in range(10)])]
    assert len(plan_variants(config_seed=0, seeds=list(range(100)), sweeps=sweeps)) == MAX_VARIANTS
    _raises(
        ConfigError,
        "the batch would make 100,100 cities; it makes at most 100,000",
        plan_variants,
        config_seed=0,
        seeds=list(range(1001)),
        sweeps=sweeps[:1],
    )
    rows = [_Row(f"r{i}", None, (), (), f"m:{i}") for i in range(2)]
    with pytest.raises(ConfigError, match="100,100 cities"):
        plan_variants(config_seed=0, manifest=rows, map_sets=[("a", ())] * 1001, sweeps=[("e.f", ["1"] * 50)])


def test_variant_inputs():
    v = Variant("x", 3, (("landuse", "/a.png", "w"),), (("a.b", "1", "w"), ("c.d", "2", "w")), "w")
    assert v.inputs() == {"seed": 3, "maps": {"landuse": "/a.png"}, "params": {"a.b": "1", "c.d": "2"}}
    assert Variant("y").inputs() == {"seed": None, "maps": {}, "params": {}}


def test_values_may_hold_equals_signs_and_kinds_capitals(tmp_path):
    _touch(tmp_path, "d=1/a.png", "m/a.png")
    sets = pair_maps(["Height=d=1", "landuse=m"], base_dir=tmp_path)
    assert [(k, w) for k, _, w in sets[0][1]] == [("Height", "--maps Height=d=1"), ("landuse", "--maps landuse=m")]
    assert parse_sweeps(["a.b=k=v", "c.d=1,x=2"]) == (["a.b=k=v"], [("c.d", ["1", "x=2"])])
    m = tmp_path / "v.csv"
    m.write_text(f"id,seed,Height\na,{MAX_SEED},m/a.png\n")
    row = read_manifest(m)[0]
    assert row.seed == MAX_SEED and row.maps[0][0] == "Height"
    m.write_text("id,landuse,a.b\na,m/a.png,1\n")
    rows = read_manifest(m)
    with pytest.raises(ConfigError, match="the landuse map is given by the manifest and by --map$"):
        plan_variants(config_seed=0, manifest=rows, fixed_maps=("landuse=x=y.png",))
    with pytest.raises(ConfigError, match="a.b is given by the manifest and by --set$"):
        plan_variants(config_seed=0, manifest=rows, fixed_sets=("a.b=k=v",))
    # a manifest in a folder whose name holds a colon: the row's number is after the last one
    assert _row_id(_Row(None, None, (), (), "/data/a:b/v.csv:12")) == "r12"
