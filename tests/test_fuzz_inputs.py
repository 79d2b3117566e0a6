"""Fuzz test of the input checks: mutated scene and study files through the CLI entry point.

The bundled scene files (studies/pc_crash, studies/validation) and study files (studies/reconstruction,
with a tiny budget) are mutated: keys deleted, values of the wrong type (strings, booleans, arrays,
tables), huge (1e30, 1e308), negative, zero, NaN and inf numbers, added keys at the edge of their range,
duplicated tables, truncated and binary files. Each case runs `crashlab.cli.main([...])` in a child
process (scenes: `simulate FILE --model impulse`; studies: `reconstruct FILE --no-progress`, a few
with `--out DIR`, all of them under -m slow), which captures stdout and stderr per case and arms a
per-case time limit (faulthandler: a hung case kills the child with its stack, the parent records the
hang and runs the rest in a new child).

A case passes when it runs (exit 0), or fails a simulation (exit 3, one line), or is refused with exit 2
and exactly one line "crashlab: error: FILE: KEY: problem" naming the mutated file: never a traceback,
never a hang. A value that is wrong whatever its key (NaN, inf, |x| >= 1e30, a boolean for a number or a
number for a boolean, an array or table for a scalar, binary or non-UTF-8 data, a duplicated table) must
be refused (exit 2); the unmutated files must run (exit 0). The default run takes a fixed sample; -m slow
runs the rest.
"""
from __future__ import annotations

import copy
import json
import math
import random
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SCENES = sorted((REPO / "studies" / "pc_crash").glob("*.toml")) + \
    sorted((REPO / "studies" / "validation").glob("*.toml"))
STUDIES = sorted((REPO / "studies" / "reconstruction").glob("*.toml"))
CASE_TIME_LIMIT = 120.0  # s per case in the child (a hang, not a slow case: the cases take < 1 s alone)
SEED = 20240610
CHILD_MEMORY = 4 << 30  # bytes of data segment (heap and private maps) for the child
DEFAULT_SHARE = {"scene": 0.3, "study": 0.2}  # of the cases in the default run; the rest is slow

# Known failures that live outside the input checks (crashlab.reconstruction, the models): case id ->
# reason. They are xfail (not strict) until fixed there.
KNOWN_FAILURES: dict[str, str] = {}


def known_failure(case) -> str | None:
    """Why a case is expected to fail today, or None."""
    return KNOWN_FAILURES.get(case["id"])


# ---------------------------------------------------------------- a small TOML writer
def _key(k) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)  # JSON escapes are TOML basic-string escapes
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def _is_aot(v) -> bool:
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def dumps(doc: dict) -> str:
    lines: list[str] = []

    def emit(table: dict, path: tuple):
        for k, v in table.items():
            if not isinstance(v, dict) and not _is_aot(v):
                lines.append(f"{_key(k)} = {_value(v)}")
        for k, v in table.items():
            if isinstance(v, dict):
                lines.append(f"\n[{'.'.join(map(_key, (*path, k)))}]")
                emit(v, (*path, k))
        for k, v in table.items():
            if _is_aot(v):
                for item in v:
                    lines.append(f"\n[[{'.'.join(map(_key, (*path, k)))}]]")
                    emit(item, (*path, k))

    emit(doc, ())
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- mutations
NUMBERS = [1e30, 1e308, -1e308, -1.0, -1e30, 0.0, math.nan, math.inf, -math.inf, 1e-300]
WRONG_TYPES = [True, "abc", [1.0, 2.0], {"a": 1.0}]


def _leaves(node, path=()):
    """(path, value) of every scalar or array-of-scalars leaf, and of every table (value None)."""
    if isinstance(node, dict):
        if path:
            yield path, None
        for k, v in node.items():
            yield from _leaves(v, (*path, k))
    elif _is_aot(node):
        for i, item in enumerate(node):
            yield from _leaves(item, (*path, i))
    else:
        yield path, node


def _get(doc, path):
    for p in path[:-1]:
        doc = doc[p]
    return doc, path[-1]


def _set(doc, path, value):
    d = copy.deepcopy(doc)
    parent, last = _get(d, path)
    parent[last] = value
    return d


def _delete(doc, path):
    d = copy.deepcopy(doc)
    parent, last = _get(d, path)
    del parent[last]
    return d


def _fmt(v) -> str:
    return "table" if isinstance(v, dict) else json.dumps(v) if isinstance(v, str) else _value(v)


def _invalid_number(v) -> bool:
    """A value no number of a scene or study may take: not finite, beyond every bound, or not a number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return True
    return not math.isfinite(v) or abs(v) >= 1e30


def _tree_mutations(doc: dict, rng: random.Random, per_leaf: int):
    """(label, mutated doc, refused) per leaf: deletion and `per_leaf` replacement values chosen for its
    type; refused is True where the value is wrong whatever the key, None where it may be valid."""
    out = []
    for path, val in _leaves(doc):
        label = ".".join(map(str, path))
        out.append((f"{label}:deleted", _delete(doc, path), None))
        if val is None:  # a table: replaced by a number
            out.append((f"{label}=5", _set(doc, path, 5), True))
            continue
        if isinstance(val, bool):
            choices = [1, "yes", 0.0]
        elif isinstance(val, (int, float)):
            choices = NUMBERS + WRONG_TYPES
        elif isinstance(val, str):
            choices = [3.0, True, "", "zzz", "a" * 300]
        else:  # an array of numbers
            choices = [[], [math.nan, 0.0], [1e308, 1e308], [1.0, 2.0, 3.0], "abc", [True, False]]
        for v in rng.sample(choices, min(per_leaf, len(choices))):
            if isinstance(val, bool) or isinstance(v, (bool, list, dict)):
                refused = True  # numbers are not booleans, booleans not numbers; no array is a scalar
            elif isinstance(val, (int, float)):
                refused = True if _invalid_number(v) else None
            elif isinstance(val, str):
                refused = True if not isinstance(v, str) else None
            else:
                refused = True  # every array value above is malformed (length, type or NaN)
            out.append((f"{label}={_fmt(v)}", _set(doc, path, v), refused))
    return out


def _text_mutations(text: str, rng: random.Random):
    """(label, bytes, refused) of file-level damage: truncation (may leave a valid file), binary data,
    encodings, duplicated tables."""
    raw = text.encode()
    out = [(f"truncated@{f:.2f}", raw[:int(len(raw) * f)], None) for f in (0.0, 0.13, 0.37, 0.5, 0.71, 0.93)]
    out.append(("binary", bytes(rng.randrange(256) for _ in range(700)), True))
    out.append(("nul-byte", raw[:len(raw) // 2] + b"\x00" + raw[len(raw) // 2:], True))
    out.append(("utf16", text.encode("utf-16"), True))
    out.append(("latin1-name", text.replace('name = "', 'name = "\xe9', 1).encode("latin-1", "replace"), True))
    tables = re.findall(r"^\[[^\[\]]+\]$", text, flags=re.M)
    if tables:  # a [table] given twice: a TOML error
        t = tables[0]
        out.append((f"duplicated {t}", (text + f"\n{t}\n").encode(), True))
    if "[[vehicles]]" in text:  # an array-of-tables element given twice: a duplicate vehicle
        block = text[text.index("[[vehicles]]"):]
        nxt = block.find("\n[[", 5)
        block = block if nxt < 0 else block[:nxt]
        out.append(("duplicated [[vehicles]]", (text + "\n" + block + "\n").encode(), True))
    return out


def _limit_mutations(text: str, path_key: str):
    """(label, bytes, refused) beyond what Python reads (issue 27: tracebacks): an integer of more than
    4,300 digits, arrays nested thousands deep (tomllib recurses), a vehicle or scene file path longer than
    a file name may be (255 bytes) at `path_key` (a scene's vehicle, a study's scene). Always in the default
    run (refused at once)."""
    out = []
    first = text.index("\n") + 1
    out.append(("integer of 5000 digits", (text[:first] + "huge = " + "9" * 5000 + "\n" + text[first:]).encode(), True))
    out.append(("arrays 5000 deep", (text[:first] + "deep = " + "[" * 5000 + "]" * 5000 + "\n" + text[first:]).encode(),
                True))
    long = re.sub(rf'^{path_key} = "[^"]*"', f'{path_key} = "{"a" * 300}.toml"', text, count=1, flags=re.M)
    assert long != text
    out.append((f"{path_key} path of 305 characters", long.encode(), True))
    return out


def _scene_additions(doc: dict):
    """Keys the bundled scenes leave out, set to values beyond their range (refused) and a few inside."""
    valid = {"vehicles.0.yaw_rate=90.0", "vehicles.0.overrides.mass=700.0", "vehicles.0.overrides.mass=3000.0",
             "road.friction=0.0+impact.friction=0"}
    out = []
    v0 = ("vehicles", 0)
    for key, vals in (("yaw_rate", [1e308, -1e3, math.nan, 90.0]), ("steer", [90.0, True, -1e30]),
                      ("x", [1e6])):
        for v in vals:
            out.append((f"vehicles.0.{key}={_fmt(v)}", _set(doc, (*v0, key), v)))
    for key, vals in (("mass", [math.inf, 1e30, 1e-30, 10.0, True, 60000.0, 700.0, 3000.0]),
                      ("yaw_inertia", [math.inf, 1e-9, 1e9]), ("cg_height", [5.0]),
                      ("cornering_stiffness", [1e30]), ("length", [0.0]), ("track", [10.0]),
                      ("wheel_radius", [math.nan]), ("multibody", [{"chassis": {"mass": math.nan}}])):
        for v in vals:
            d = copy.deepcopy(doc)
            d["vehicles"][0].setdefault("overrides", {})[key] = v
            out.append((f"vehicles.0.overrides.{key}={_fmt(v)}", d))
    for key, v in (("x", 1e30), ("length", 1e30), ("width", -1.0), ("heading", math.inf), ("length", 0.01)):
        d = copy.deepcopy(doc)
        barrier = {"x": 60.0, "y": 60.0, "heading": 0.0, "length": 10.0, "width": 1.0}
        barrier[key] = v
        d.setdefault("barriers", []).append(barrier)
        out.append((f"barriers.+.{key}={_fmt(v)}", d))
    for point, plane in (([1e30, 0.0], 90.0), ([0.0, 0.0], 1e308), ([math.nan, 0.0], 0.0)):
        d = copy.deepcopy(doc)
        d.setdefault("impact", {}).update(point=point, plane_angle=plane)
        out.append((f"impact.point={_fmt(point)},plane_angle={_fmt(plane)}", d))
    for fr in (0.0, True):
        out.append((f"road.friction={_fmt(fr)}+impact.friction=0", _set(_set(doc, ("road",), {"friction": fr}),
                                                                          ("impact", "friction"), 0.0)))
    out.append(("unknown key", _set(doc, ("colour",), "red")))
    out.append(("vehicles.0.unknown key", _set(doc, (*v0, "sped"), 50.0)))
    return [(lab, d, None if lab in valid else True) for lab, d in out]


def _tiny_study(doc: dict, path: Path, polish: int) -> dict:
    """The study with a tiny budget (one generation of 4, polish 0 or 4 evaluations, a [refine] of 2
    evaluations), evaluated in this process, its scene as an absolute path."""
    d = copy.deepcopy(doc)
    d["scene"] = (path.parent / d["scene"]).resolve().as_posix()
    d.setdefault("optimizer", {}).update(pop_size=4, generations=1)
    d["polish"] = {"evaluations": polish}
    if isinstance(d.get("refine"), dict):  # a multibody refine polishes for a minute: the input's check is the case
        d["refine"]["evaluations"] = 2
    # evaluations in this process (no worker process per run); the child's per-case limit catches hangs
    d.setdefault("execution", {})["timeout_s"] = 0.0
    return d


def _study_additions(doc: dict):
    """Study keys set beyond any range (refused; a seed of 2^40 may be valid)."""
    out = []
    for key, v in (("dt", 1e308), ("dt", math.nan), ("dt", True)):
        out.append((f"model_options.{key}={_fmt(v)}", _set(doc, ("model_options",), {key: v})))
    for key, v in (("pop_size", 10 ** 9), ("pop_size", 1e9), ("generations", 10 ** 12), ("seed", -1),
                   ("seed", 2 ** 40), ("pop_size", 4.5)):
        out.append((f"optimizer.{key}={_fmt(v)}", _set(doc, ("optimizer", key), v)))
    out.append(("optimizer.options.unknown", _set(doc, ("optimizer", "options"), {"zzz": 1.0})))
    for v in (1e18, 1e308, -1e30):
        d = copy.deepcopy(doc)
        d["evidence"] = {"rest": {"V1": {"x": v, "y": 0.0, "heading": 0.0}}}
        out.append((f"evidence.rest.V1.x={_fmt(v)}", d))
    for lo, hi in ((-1e308, 1e308), (0.0, 1e30), (math.nan, 1.0), (30.0, 30.0)):
        d = copy.deepcopy(doc)
        d["free"][0].update(lower=lo, upper=hi)
        out.append((f"free.0=[{_fmt(lo)}, {_fmt(hi)}]", d))
    out.append(("scene=missing.toml", _set(doc, ("scene",), "missing.toml")))
    out.append(("scene=.", _set(doc, ("scene",), ".")))
    out.append(("unknown key", _set(doc, ("colour",), "red")))
    return [(lab, d, None if lab == f"optimizer.seed={2 ** 40}" else True) for lab, d in out]


def all_cases() -> list[dict]:
    """Every fuzz case: id, kind (scene/study), content (bytes), refused (True: must exit 2; False: must
    run, exit 0; None: either). Deterministic: a seeded sample of the
    per-leaf mutations of each file, the additions of two scenes and two studies, the file-level damage
    of every scene and of three studies."""
    rng = random.Random(SEED)
    cases = []
    for path in SCENES:
        text = path.read_text()
        doc = tomllib.loads(text)
        muts = rng.sample(_tree_mutations(doc, rng, per_leaf=2), 20)
        if path.stem in ("side", "rigid_wall"):
            muts += _scene_additions(doc)
        muts = [(lab, dumps(d).encode(), r) for lab, d, r in [("unmutated", doc, False), *muts]]
        muts += _text_mutations(text, rng)
        cases += [{"id": f"scene:{path.stem}:{lab}", "kind": "scene", "content": data, "refused": r}
                  for lab, data, r in muts]
    for k, path in enumerate(STUDIES):
        doc = _tiny_study(tomllib.loads(path.read_text()), path, polish=4 * (k % 2))
        muts = rng.sample(_tree_mutations(doc, rng, per_leaf=2), 8)
        if path.stem in ("case1", "twin1"):
            muts += _study_additions(doc)
        muts = [(lab, dumps(d).encode(), r) for lab, d, r in [("unmutated", doc, False), *muts]]
        if path.stem in ("case1", "case3", "twin1"):
            muts += _text_mutations(dumps(doc), rng)
        cases += [{"id": f"study:{path.stem}:{lab}", "kind": "study", "content": data, "refused": r}
                  for lab, data, r in muts]
    for kind, path, key in (("scene", SCENES[0], "vehicle"), ("study", STUDIES[0], "scene")):
        text = path.read_text() if kind == "scene" else dumps(_tiny_study(tomllib.loads(path.read_text()), path, 0))
        cases += [{"id": f"{kind}:{path.stem}:limit:{lab}", "kind": kind, "content": data, "refused": r}
                  for lab, data, r in _limit_mutations(text, key)]
    seen = set()
    for c in cases:  # ids are the test ids: unique
        base, n = c["id"], 2
        while c["id"] in seen:
            c["id"], n = f"{base}#{n}", n + 1
        seen.add(c["id"])
    return cases


def split(cases):
    """A fixed seeded sample for the default run, the rest for -m slow."""
    rng = random.Random(SEED + 1)
    default, slow = [], []
    for c in cases:
        if c["id"].endswith(":unmutated") or ":limit:" in c["id"]:  # the bases always run: they must run
            #                                                           (exit 0); the limits: refused at once
            default.append(c)
            continue
        share = DEFAULT_SHARE[c["kind"]]
        (default if rng.random() < share else slow).append(c)
    return default, slow


CASES = all_cases()
DEFAULT_CASES, SLOW_CASES = split(CASES)
BY_ID = {c["id"]: c for c in CASES}


# ---------------------------------------------------------------- running the cases in a child process
def _argv(case, file: Path, out_dir: Path | None):
    if case["kind"] == "scene":
        return ["simulate", str(file), "--model", "impulse"]
    argv = ["reconstruct", str(file), "--no-progress"]
    return argv + (["--out", str(out_dir)] if out_dir is not None else [])


def run_cases(cases, workdir: Path, with_out: bool) -> dict[str, dict]:
    """Run the cases in child processes; id -> {rc, stderr, error, hang}. A hang (the case's time
    limit) or a crash of the child is recorded against the case it was running; the rest go on."""
    workdir.mkdir(parents=True, exist_ok=True)
    manifest = []
    for k, c in enumerate(cases):
        f = workdir / f"case{k:04d}.toml"
        f.write_bytes(c["content"])
        out_dir = workdir / f"out{k:04d}" if (with_out or k % 10 == 0) and c["kind"] == "study" else None
        manifest.append({"id": c["id"], "argv": _argv(c, f, out_dir), "file": str(f), "refused": c["refused"]})
    results: dict[str, dict] = {}
    todo = manifest
    while todo:
        mpath, rpath = workdir / "manifest.json", workdir / "results.jsonl"
        mpath.write_text(json.dumps(todo))
        rpath.write_text("")
        code = (f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
                f"from test_fuzz_inputs import _child; _child({str(mpath)!r}, {str(rpath)!r})")
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True,
                              text=True, cwd=workdir, timeout=CASE_TIME_LIMIT * len(todo) + 120)
        for line in rpath.read_text().splitlines():
            r = json.loads(line)
            results[r["id"]] = r
        done = [m for m in todo if m["id"] in results]
        if len(done) == len(todo):
            break
        stuck = todo[len(done)]  # the case the child was running when it died
        results[stuck["id"]] = {"id": stuck["id"], "rc": None, "stderr": proc.stderr[-3000:],
                                "error": f"child died (exit {proc.returncode}): hang or crash", "file": stuck["file"]}
        todo = todo[len(done) + 1:]
    return results


def _child(manifest_path: str, results_path: str):
    """Child process: each case through crashlab.cli.main in this process, stdout/stderr captured."""
    import contextlib
    import faulthandler
    import io
    import resource
    import time
    import traceback
    import warnings

    import matplotlib
    matplotlib.use("Agg")
    from crashlab.cli import main
    # a case that allocates without bound (a population of 1e9) fails here with MemoryError, not by the
    # out-of-memory killer of a machine the child shares
    resource.setrlimit(resource.RLIMIT_DATA, (CHILD_MEMORY, CHILD_MEMORY))
    # warm-up outside the per-case limits: the first simulation loads (or compiles) the impulse kernel,
    # the optimizers' modules their numba functions
    import crashlab
    from crashlab.registry import OPTIMIZERS, available_optimizers, load
    crashlab.simulate(crashlab.load_scene(SCENES[0]))
    for name in available_optimizers():
        load(OPTIMIZERS, name)
    manifest = json.loads(Path(manifest_path).read_text())
    with open(results_path, "a") as res:
        for m in manifest:
            sys.__stderr__.write(f"fuzz case {m['id']}\n")
            sys.__stderr__.flush()
            faulthandler.dump_traceback_later(CASE_TIME_LIMIT, exit=True)
            out, err = io.StringIO(), io.StringIO()
            rec = {"id": m["id"], "file": m["file"], "refused": m["refused"], "rc": None, "error": None}
            t0 = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                        rec["rc"] = main(m["argv"])
                except SystemExit as e:
                    rec["rc"] = e.code if isinstance(e.code, int) else 1
                    rec["error"] = f"SystemExit({e.code!r})"
                except BaseException as e:  # noqa: BLE001 - a traceback is what the fuzz test looks for
                    tb = traceback.format_exception(e)
                    rec["error"] = tb[-1].strip()
                    rec["where"] = "".join(tb[-3:-1])[-600:]
            faulthandler.cancel_dump_traceback_later()
            rec["seconds"] = round(time.perf_counter() - t0, 3)
            rec["stderr"] = err.getvalue()[-2000:]
            rec["warnings"] = sorted({f"{w.category.__name__}: {w.message}" for w in caught
                                      if issubclass(w.category, RuntimeWarning)})[:3]
            res.write(json.dumps(rec) + "\n")
            res.flush()


def check(r: dict):
    """The contract of one case (see the module docstring)."""
    assert r["error"] is None, f"{r['error']}\n{r.get('where', '')}\n{r['stderr'][-1500:]}"
    if r["refused"] is False:  # a bundled file (tiny budget) runs: the mutations test the checks
        assert r["rc"] == 0, r["stderr"]
    if r["refused"]:  # a value wrong whatever its key (NaN, inf, 1e30, a bool for a number, binary data)
        assert r["rc"] == 2, f"accepted (exit {r['rc']}): {r['stderr'][-500:]}"
    lines = r["stderr"].strip().splitlines()
    assert r["rc"] in (0, 2, 3), f"exit {r['rc']}: {r['stderr']}"
    assert "Traceback" not in r["stderr"], r["stderr"]
    if r["rc"] in (2, 3):
        assert len(lines) == 1, f"exit {r['rc']} with {len(lines)} lines:\n{r['stderr']}"
    if r["rc"] == 2:
        prefix = f"crashlab: error: {r['file']}: "
        assert lines[0].startswith(prefix), f"not naming the file: {lines[0]}"
        assert re.match(r"[^:]+: \S", lines[0][len(prefix):]), f"no key: {lines[0]}"
    if r["rc"] == 0:
        assert not r["warnings"], f"ran with numerical warnings: {r['warnings']}"


def _params(cases):
    return [pytest.param(c["id"], marks=pytest.mark.xfail(reason=known_failure(c), strict=False))
            if known_failure(c) else c["id"] for c in cases]


@pytest.fixture(scope="module")
def default_results(tmp_path_factory):
    return run_cases(DEFAULT_CASES, tmp_path_factory.mktemp("fuzz_default"), with_out=False)


@pytest.fixture(scope="module")
def slow_results(tmp_path_factory):
    return run_cases(SLOW_CASES, tmp_path_factory.mktemp("fuzz_slow"), with_out=True)


def test_the_fuzz_set_is_large_and_varied():
    kinds = {"deleted": ":deleted", "wrong type": '="abc"', "huge": "=1e+308", "negative": "=-1.0",
             "NaN": "=nan", "inf": "=inf", "duplicated table": "duplicated ", "truncated": "truncated@",
             "binary": "binary"}
    assert len(CASES) >= 250
    assert sum(c["id"].endswith(":unmutated") for c in DEFAULT_CASES) == len(SCENES) + len(STUDIES)
    for name, mark in kinds.items():
        for kind in ("scene", "study"):
            assert any(mark in c["id"] for c in CASES if c["kind"] == kind), (name, kind)
    assert len(DEFAULT_CASES) >= 60 and len(SLOW_CASES) >= 150


@pytest.mark.parametrize("case_id", _params(DEFAULT_CASES))
def test_fuzz_case(case_id, default_results):
    check(default_results[case_id])


@pytest.mark.slow
@pytest.mark.parametrize("case_id", _params(SLOW_CASES))
def test_fuzz_case_slow(case_id, slow_results):
    check(slow_results[case_id])
