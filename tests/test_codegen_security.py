"""What reaches the C compiler is fixed by optikin, and the compiled-code cache loads only the user's own builds.

A preset's ``flags`` come from an allow-list of optimisation flags, its ``compiler`` is a
name from a fixed set found on PATH; a library in the cache is loaded only when it and its
record belong to the current user, are not group/world-writable and match the hash of what
it is built from; anything else is rebuilt.
"""

from __future__ import annotations

import json
import os
import shutil
import stat
import subprocess
import textwrap
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from optikin import codegen
from optikin.codegen import ALLOWED_FLAGS, CompiledFunction, cache_dir, cached_library, check_flag, check_flags
from optikin.errors import SolverError, SpecError
from optikin.runner import solve
from optikin.solvers import load_preset

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="no gcc on PATH")

PROBLEM = """\
name: small-compiled
title: a small compiled fk problem
kind: fk
arm:
  type: constant_curvature
  params: {section_lengths: [0.18, 0.18]}
data:
  source: random
  seed: 3
  samples: 4
solver: casadi-compiled
"""

WRAPPER = '["-O3", "-wrapper", "/bin/sh,-c,touch PWNED; exec \\"$0\\" \\"$@\\""]'


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """A fresh per-user cache under ``tmp_path``; the folder the libraries go to."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path / "xdg" / "optikin"


@pytest.fixture
def compiles(monkeypatch) -> list[list[str]]:
    """The compile commands run (``--version`` queries and other programs left out)."""
    runs: list[list[str]] = []

    class Recording(subprocess.Popen):
        def __init__(self, argv, *args, **kwargs):
            if "-shared" in argv:
                runs.append(list(argv))
            super().__init__(argv, *args, **kwargs)

    monkeypatch.setattr(codegen.subprocess, "Popen", Recording)
    return runs


def small_function(name: str = "sec_f") -> ca.Function:
    x = ca.SX.sym("x", 3)
    return ca.Function(name, [x], [ca.vertcat(ca.sin(x[0]) * x[1], x[2] ** 2, ca.cos(x[1]))])


def shadowing_preset(folder: Path, options: str) -> Path:
    """``solvers/casadi-compiled.yaml`` in ``folder``, shadowing the shipped preset."""
    path = folder / "solvers" / "casadi-compiled.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"name: casadi-compiled\nbackend: casadi_compiled\noptions:\n{textwrap.indent(options, '  ')}\n")
    return path


# --------------------------------------------------------------------------- presets


def test_wrapper_flag_in_a_shadowing_preset_is_refused_before_anything_runs(tmp_path, monkeypatch, cache, compiles):
    monkeypatch.chdir(tmp_path)
    preset = shadowing_preset(tmp_path, f"flags: {WRAPPER}")
    problem = tmp_path / "problems" / "small-compiled.yaml"
    problem.parent.mkdir()
    problem.write_text(PROBLEM)
    with pytest.raises(SpecError) as err:
        solve(str(problem))
    assert err.value.field == "options.flags.1"
    assert Path(err.value.path).resolve() == preset.resolve()
    assert "'-wrapper' is not allowed" in str(err.value)
    assert compiles == [] and not (tmp_path / "PWNED").exists() and not cache.exists()


@pytest.mark.parametrize(
    "options, field",
    [
        ('flags: ["-B/tmp/evil"]', "options.flags.0"),
        ('flags: ["-O2", "@/tmp/flags.txt"]', "options.flags.1"),
        ('flags: ["-specs=/tmp/evil.specs"]', "options.flags.0"),
        ('flags: ["-fplugin=/tmp/evil.so"]', "options.flags.0"),
        ('flags: ["-O3", "-o", "/tmp/x"]', "options.flags.1"),
        ('flags: ["-DEVIL=1"]', "options.flags.0"),
        ('flags: "-O3"', "options.flags"),
        ("compiler: /tmp/evil/gcc", "options.compiler"),
        ("compiler: tcc", "options.compiler"),
        ("linker: ld", "options.linker"),
    ],
)
def test_preset_options_outside_the_allow_lists_are_named(tmp_path, options, field):
    preset = shadowing_preset(tmp_path, options)
    with pytest.raises(SpecError) as err:
        load_preset(str(preset))
    assert err.value.field == field and err.value.path == str(preset)


def test_the_shipped_preset_and_allowed_flags_load():
    assert load_preset("casadi-compiled").options.flags == ["-O3"]
    for flag in (
        "-O0",
        "-O1",
        "-O2",
        "-O3",
        "-Os",
        "-march=native",
        "-mtune=native",
        "-ffast-math",
        "-funroll-loops",
        "-fno-math-errno",
    ):
        assert check_flag(flag) == flag and flag in ALLOWED_FLAGS


@pytest.mark.parametrize(
    "flag",
    ["-wrapper", "-B", "-specs=x", "@file", "-fplugin=x.so", "-o", "-Dx", "-I.", "-L.", "-lfoo", "-O3 -wrapper", ""],
)
def test_check_flag_refuses_what_is_not_an_optimisation_flag(flag):
    with pytest.raises(ValueError, match="not allowed"):
        check_flag(flag)
    with pytest.raises(ValueError, match=r"^flags\.1: "):
        check_flags(["-O2", flag])


def test_compiled_function_validates_its_flags_and_compiler_too(cache, compiles):
    f = small_function()
    with pytest.raises(SolverError, match="'-wrapper' is not allowed"):
        CompiledFunction(f, ("-O3", "-wrapper", "/bin/sh,-c,touch PWNED"))
    with pytest.raises(SolverError, match="compiler '/usr/bin/gcc' is not allowed"):
        CompiledFunction(f, ("-O3",), "/usr/bin/gcc")
    assert compiles == []


# --------------------------------------------------------------------------- the cache


def test_cache_is_per_user_and_private(tmp_path, monkeypatch, cache, compiles):
    compiled = CompiledFunction(small_function())
    assert compiled.library.parent == cache
    assert stat.S_IMODE(os.stat(cache).st_mode) == 0o700
    assert stat.S_IMODE(os.stat(compiled.library).st_mode) & 0o022 == 0
    record = json.loads(compiled.library.with_suffix(".json").read_text())
    assert record["flags"] == ["-O3"] and record["compiler"] == shutil.which("gcc") and record["compiler_version"]
    assert len(compiles) == 1

    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache_dir() == tmp_path / "home" / ".cache" / "optikin"
    assert stat.S_IMODE(os.stat(tmp_path / "home" / ".cache" / "optikin").st_mode) == 0o700


def test_an_open_cache_folder_is_made_private(cache):
    cache.mkdir(parents=True, mode=0o777)
    os.chmod(cache, 0o777)
    assert cache_dir() == cache and stat.S_IMODE(os.stat(cache).st_mode) == 0o700


def test_a_cache_folder_that_is_a_link_is_refused(tmp_path, cache):
    (tmp_path / "elsewhere").mkdir()
    cache.parent.mkdir()
    cache.symlink_to(tmp_path / "elsewhere")
    with pytest.raises(SolverError, match="not a folder"):
        cache_dir()


def test_a_valid_library_is_loaded_without_compiling(cache, compiles):
    first = CompiledFunction(small_function())
    again = CompiledFunction(small_function())
    assert again.library == first.library and len(compiles) == 1
    x = np.array([[0.3, 0.5, -0.2], [1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(again(x), first(x))


def test_other_flags_are_another_library(cache, compiles):
    a = CompiledFunction(small_function(), ("-O3",))
    b = CompiledFunction(small_function(), ("-O2",))
    assert a.library != b.library and len(compiles) == 2


def tampered(compiles, change) -> tuple[Path, bytes]:
    """Build (without loading), change the cached files with ``change(library, record)``, build and load again.

    Returns the library and the bytes of the first build.
    """
    library = cached_library(small_function())
    good = library.read_bytes()
    change(library, library.with_suffix(".json"))
    assert len(compiles) == 1
    rebuilt = CompiledFunction(small_function())
    assert rebuilt.library == library
    return library, good


def test_a_planted_library_with_the_right_name_is_rebuilt(cache, compiles):
    def plant(library, record):
        library.write_bytes(b"\x7fELF not what optikin built")

    library, good = tampered(compiles, plant)
    assert len(compiles) == 2 and library.read_bytes() == good


def test_a_library_whose_record_has_another_hash_is_rebuilt(cache, compiles):
    def rehash(library, record):
        data = json.loads(record.read_text())
        data["hash"] = "0" * 64
        record.write_text(json.dumps(data))

    library, _ = tampered(compiles, rehash)
    assert len(compiles) == 2 and json.loads(library.with_suffix(".json").read_text())["hash"] != "0" * 64


def test_a_library_without_its_record_is_rebuilt(cache, compiles):
    tampered(compiles, lambda library, record: record.unlink())
    assert len(compiles) == 2


@pytest.mark.parametrize("which", ["library", "record"])
def test_a_world_writable_cache_entry_is_rebuilt(cache, compiles, which):
    def open_up(library, record):
        os.chmod(library if which == "library" else record, 0o666)

    library, _ = tampered(compiles, open_up)
    assert len(compiles) == 2
    for path in (library, library.with_suffix(".json")):
        assert stat.S_IMODE(os.stat(path).st_mode) & 0o022 == 0


def test_a_library_that_is_a_link_is_rebuilt(tmp_path, cache, compiles):
    def link(library, record):
        target = tmp_path / "lib.so"
        shutil.copy(library, target)
        library.unlink()
        library.symlink_to(target)

    library, _ = tampered(compiles, link)
    assert len(compiles) == 2 and not library.is_symlink()
