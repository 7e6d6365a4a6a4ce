"""``optikin export`` writes no text it did not choose, and refuses an ``--out`` it cannot write into.

A problem file under folders whose names hold C (``*/``, a line of code, ``/*``), make and shell
syntax (``$(shell ...)``, backticks), quotes, spaces and non-ASCII is exported, built with make and
with CMake and its example run: the build succeeds and no file appears anywhere but in the output
and build folders (before, the folder names reached line 1 of the header and the example ran
``system("touch PWNED")``). Each escaping function of :mod:`optikin.export._escape` is checked
against hostile strings by something independent of it: a C-comment scanner and ``gcc
-fsyntax-only`` for comments, the bytes a compiled program prints for string literals, ``make`` and
``cmake -P`` for build-file values. Every ``--out`` that is empty, a file, under a file, a dangling
symlink or not creatable is exit 2 with one line and nothing written.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import subprocess
from pathlib import Path

import casadi as ca
import pytest

from optikin import codegen
from optikin.cli import EXIT_BAD_INPUT, main
from optikin.errors import SpecError
from optikin.export import _generated, export
from optikin.export._escape import c_comment, c_identifier, c_string, cmake_value, make_word, problem_comment
from optikin.results import OutputError

REPO = Path(__file__).resolve().parents[2]
PROBLEM = "cc-two-section-fk"

HOSTILE_FOLDER = (
    'e/*/\n#include <stdlib.h>\n__attribute__((constructor)) static void p(void){system("touch C_PWNED");}\n/*x'
    "/$(shell touch MAKE_PWNED)/`touch BACKTICK_PWNED`/'q\"/a b/\u00e9 \u00fc \u4e2d/${x};$ENV{HOME}"
)
"""Nested folders: the issue's reproducer (C between ``*/`` and ``/*``), then make, shell and CMake syntax."""

PWNED = {"C_PWNED", "MAKE_PWNED", "BACKTICK_PWNED"}
"""The files :data:`HOSTILE_FOLDER` and :data:`OUT_FOLDERS` would create if their text ran."""

OUT_FOLDERS = ("a b", "$(shell touch MAKE_PWNED)", "`touch BACKTICK_PWNED`", "\u00e9 \u4e2d", "${x}", "$ENV{HOME}")
"""Nested output folders CMake itself can build in (its own modules fail under a quote, ``;`` or a newline)."""

HOSTILE = (
    "*/",
    "/*",
    "*/ int evil = 1; /*",
    "a\nb",
    "a\r\nb",
    "tab\there",
    "end\\",
    "??/",
    "??/\n*/",
    "*\\\n/",
    "??=define X",
    '"; system("x"); "',
    "'",
    '\\"',
    "\x00nul",
    "\x017",
    "\n123",
    "\x1b[31m",
    "\u2028",
    "\u00e9\u4e2d",
    "$(shell touch X)",
    "`touch X`",
    "${CMAKE_COMMAND}",
    "$ENV{HOME}",
    "$<1:x>",
    '") file(WRITE pwned x) #(',
    "a;b",
    "@x@",
    "",
)
"""Strings meant to break out of a comment, a string literal, a Makefile or a CMake argument."""

needs_cc = pytest.mark.skipif(shutil.which("cc") is None or shutil.which("make") is None, reason="needs cc and make")
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
needs_cmake = pytest.mark.skipif(shutil.which("cmake") is None, reason="needs cmake")


def snapshot(root: Path, *skip: Path) -> set[str]:
    """Every path under ``root`` (symlinks not followed), but those under ``skip``."""
    found = set()
    for folder, folders, files in os.walk(root):
        here = Path(folder)
        folders[:] = [name for name in folders if here / name not in skip]
        found.update(str(here / name) for name in folders + files)
    return found


def pwned(root: Path) -> list[str]:
    """The files the hostile names would create, wherever they are under ``root``."""
    return [path for path in snapshot(root) if Path(path).name in PWNED]


def hostile_problem(root: Path) -> Path:
    """The shipped problem copied under :data:`HOSTILE_FOLDER` inside ``root``."""
    folder = root / HOSTILE_FOLDER
    folder.mkdir(parents=True)
    target = folder / f"{PROBLEM}.yaml"
    shutil.copy(REPO / "problems" / f"{PROBLEM}.yaml", target)
    return target


def export_and_build(root: Path, problem: Path, what: str, out: Path, cmake: bool) -> list[str]:
    """``optikin export`` then make (and CMake into ``root/cmake-build``), running each example in ``root``."""
    assert main(["export", str(problem), "--what", what, "--out", str(out)]) == 0
    header = (out / f"optikin_{what.replace('-', '_')}.h").read_bytes()
    assert header.isascii()
    assert header.startswith(b"/* optikin_") and problem.stem.encode() in header.splitlines()[0]
    subprocess.run(["make", "-s", "-C", str(out), "CFLAGS=-O0"], check=True, capture_output=True, timeout=120)
    outputs = [subprocess.run([str(out / "example")], cwd=root, capture_output=True, text=True, timeout=60, check=True)]
    if cmake:
        build = root / "cmake-build"
        for command in (
            ["cmake", "-S", str(out), "-B", str(build), "-DCMAKE_BUILD_TYPE=Debug"],
            ["cmake", "--build", str(build)],
        ):
            subprocess.run(command, check=True, capture_output=True, timeout=300)
        run = subprocess.run([str(build / "example")], cwd=root, capture_output=True, text=True, timeout=60, check=True)
        outputs.append(run)
    return [run.stdout for run in outputs]


# --------------------------------------------------------------------------- whole exports
@needs_cc
def test_fk_from_a_hostile_folder_builds_with_make_and_writes_nowhere_else(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problem = hostile_problem(tmp_path)
    out = tmp_path / "out"
    before = snapshot(tmp_path)
    (stdout,) = export_and_build(tmp_path, problem, "fk", out, cmake=False)
    assert stdout.split()[:2] == ["fk_dq", "0"]
    assert snapshot(tmp_path, out) == before
    assert pwned(tmp_path) == []
    assert {p.name for p in out.iterdir()} == {
        "optikin_fk.c",
        "optikin_fk.h",
        "main.c",
        "Makefile",
        "CMakeLists.txt",
        "README.md",
        "configurations.txt",
        "optikin_fk.o",
        "liboptikin_fk.a",
        "example",
    }


@needs_cc
@needs_cmake
@pytest.mark.slow
def test_fk_from_a_hostile_folder_into_a_hostile_folder_builds_with_cmake_as_with_make(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    problem = hostile_problem(tmp_path)
    out = tmp_path.joinpath(*OUT_FOLDERS, "out")
    before = snapshot(tmp_path)
    made, cmade = export_and_build(tmp_path, problem, "fk", out, cmake=True)
    assert made == cmade and made.split()[:2] == ["fk_dq", "0"]
    assert snapshot(tmp_path, tmp_path / OUT_FOLDERS[0], tmp_path / "cmake-build") == before
    assert pwned(tmp_path) == []


@needs_cc
def test_ik_step_from_a_hostile_folder_builds_and_writes_nowhere_else(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / HOSTILE_FOLDER
    folder.mkdir(parents=True)
    problem = folder / "cc-ik-position.yaml"
    shutil.copy(REPO / "problems" / "cc-ik-position.yaml", problem)
    out = tmp_path / "out"
    before = snapshot(tmp_path)
    (stdout,) = export_and_build(tmp_path, problem, "ik-step", out, cmake=False)
    assert stdout.split()[0] == "0"  # the first target solved
    assert snapshot(tmp_path, out) == before
    assert pwned(tmp_path) == []
    header = (out / "optikin_ik_step.h").read_text()
    assert header.startswith("/* optikin_ik_step.h: inverse kinematics of optikin problem cc-ik-position,")


@needs_cc
def test_an_output_folder_with_a_hostile_name_builds_with_make(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / HOSTILE_FOLDER / "out"
    before = snapshot(tmp_path)
    export_and_build(tmp_path, Path(PROBLEM), "fk", out, cmake=False)
    assert snapshot(tmp_path, tmp_path / HOSTILE_FOLDER.split("/")[0]) == before
    assert pwned(tmp_path) == []


@needs_gcc
@pytest.mark.parametrize("problem, what", [("cbha-ph-shape", "ph-shape"), ("track-nominal", "qp-step")])
def test_ph_shape_and_qp_step_from_a_hostile_folder_are_plain_c(tmp_path, monkeypatch, problem, what):
    """Every file is ASCII, the header's comments hold no code and gcc accepts the example with its header."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / HOSTILE_FOLDER
    folder.mkdir(parents=True)
    shutil.copy(REPO / "problems" / f"{problem}.yaml", folder)
    out = tmp_path / "out"
    assert main(["export", str(folder / f"{problem}.yaml"), "--what", what, "--out", str(out)]) == 0
    stem = f"optikin_{what.replace('-', '_')}"
    assert all(path.read_bytes().isascii() for path in out.iterdir())
    header = (out / f"{stem}.h").read_text()
    assert header.startswith(f"/* {stem}.h: ") and problem in header.splitlines()[0]
    assert "__attribute__" not in comments(header)[1] and "#include <stdlib.h>" not in comments(header)[1]
    command = ["gcc", "-std=c99", "-fsyntax-only", "-Wall", "-Werror", "main.c"]
    run = subprocess.run(command, cwd=out, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert pwned(tmp_path) == []


def test_casadi_names_that_are_not_identifiers_are_refused():
    """CasADi writes Function, input and output names into comments and strings unescaped."""
    x = ca.SX.sym("x", 2)
    with pytest.raises(SpecError, match="input or output name of f: .*not a C identifier"):
        _generated([ca.Function("f", [x], [x], ["q*/ int evil; /*"], ["y"])], "optikin_fk")
    with pytest.raises(SpecError, match="input or output name"):
        _generated([ca.Function("f", [x], [x], ["q"], ["y\nz"])], "optikin_fk")


# --------------------------------------------------------------------------- C comments
def translation_phases(text: str) -> str:
    """C99 translation phases 1-2: trigraphs replaced, backslash-newlines removed."""
    trigraphs = dict(zip("=(/)'<!>-", "#[\\]^{|}~"))
    text = re.sub(r"\?\?([=(/)'<!>-])", lambda m: trigraphs[m.group(1)], text)
    return text.replace("\\\n", "")


def comments(text: str) -> tuple[list[str], str]:
    """The block comments of C ``text`` and what is left outside them (no strings in ``text``)."""
    text = translation_phases(text)
    found, code, i = [], [], 0
    while i < len(text):
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            assert end >= 0, "unterminated comment"
            found.append(text[i + 2 : end])
            i = end + 2
        else:
            code.append(text[i])
            i += 1
    return found, "".join(code)


@pytest.mark.parametrize("text", HOSTILE)
def test_a_comment_is_printable_ascii_without_comment_or_splice_characters(text):
    safe = c_comment(text)
    assert all(" " <= c <= "~" for c in safe)
    assert not set(safe) & set("*/\\?")
    assert len(safe) == len(text)


@pytest.mark.parametrize("text", ["cc-two-section-fk", "S1, theta1, phi1", "x0 = 0.18 (m) [rad], -r <= qdot <= r"])
def test_ordinary_comment_text_is_kept(text):
    assert c_comment(text) == text


def test_no_comment_is_closed_early_by_the_scanner_and_by_gcc(tmp_path):
    """Each hostile string between each pair of template characters stays inside its one comment."""
    lines = []
    for text in filter(None, HOSTILE):  # the template's characters alone are the template's business
        for before in ("", "*", "/", "?"):
            for after in ("", "*", "/", "?", "\\"):
                comment = f"/* {before}{c_comment(text)}{after}\n */"
                found, code = comments(comment)
                assert len(found) == 1 and code == "", (text, comment)
                lines.append(comment)
    source = "\n".join(lines) + "\nint ok;\n"
    found, code = comments(source)
    assert len(found) == len(lines) and code.split() == ["int", "ok;"]
    if shutil.which("gcc"):
        path = tmp_path / "comments.c"
        path.write_text(source, encoding="ascii")
        command = ["gcc", "-std=c99", "-fsyntax-only", "-Wall", "-Wcomment", "-Wtrigraphs", "-Werror", str(path)]
        run = subprocess.run(command, capture_output=True, text=True, timeout=60)
        assert run.returncode == 0, run.stderr


@pytest.mark.parametrize(
    "problem, expected",
    [
        ("cc-two-section-fk", "cc-two-section-fk"),
        ("/a/*/\n#include <x>\n/*x/cc-two-section-fk.yaml", "cc-two-section-fk"),
        ("e/*", "_"),
        ("x/\u00e9*.yaml", "__"),
    ],
)
def test_a_problem_is_named_by_its_file_stem_only(problem, expected):
    assert problem_comment(problem) == expected


def test_the_scanner_sees_the_unescaped_problem_close_the_comment():
    """The check can fail: the header line as it was written before escaping holds code."""
    found, code = comments(f"/* problem {HOSTILE_FOLDER} (cc) */\n")
    assert "__attribute__((constructor))" in code


# --------------------------------------------------------------------------- C string literals
@needs_gcc
def test_string_literals_hold_exactly_the_bytes_of_the_text(tmp_path):
    texts = [*HOSTILE, "optikin_fk", "fk_dq", "??(??)??<??>"]
    declarations = "".join(f"static const char s{i}[] = {c_string(t)};\n" for i, t in enumerate(texts))
    prints = "".join(
        f'  for (k = 0; k < sizeof s{i} - 1; ++k) printf("%02x", (unsigned char)s{i}[k]);\n  printf("\\n");\n'
        for i in range(len(texts))
    )
    source = f"#include <stdio.h>\n{declarations}int main(void) {{\n  size_t k;\n{prints}  return 0;\n}}\n"
    (tmp_path / "strings.c").write_text(source, encoding="ascii")
    command = ["gcc", "-std=c99", "-Wall", "-Wtrigraphs", "-Werror", "strings.c", "-o", "strings"]
    subprocess.run(command, cwd=tmp_path, check=True, capture_output=True, timeout=60)
    run = subprocess.run([str(tmp_path / "strings")], capture_output=True, text=True, timeout=60, check=True)
    assert run.stdout.split("\n")[:-1] == [t.encode("utf-8").hex() for t in texts]


@pytest.mark.parametrize("text", HOSTILE)
def test_a_string_literal_is_one_line_of_printable_ascii(text):
    literal = c_string(text)
    assert literal.startswith('"') and literal.endswith('"') and literal.isascii() and literal.isprintable()
    assert '"' not in literal[1:-1].replace('\\"', "") and "?" not in literal


# --------------------------------------------------------------------------- identifiers
@pytest.mark.parametrize("name", ["optikin_fk", "_x", "fk_dq_cg", "S1", "a" * 63])
def test_identifiers_of_the_allow_list_are_kept(name):
    assert c_identifier(name, "stem") == name


@pytest.mark.parametrize(
    "name, reason",
    [
        *((text, "not a C identifier") for text in HOSTILE),
        ("1a", "not a C identifier"),
        ("a b", "not a C identifier"),
        ("a-b", "not a C identifier"),
        ("\u00e9", "not a C identifier"),
        ("x\n", "not a C identifier"),
        (None, "not a C identifier"),
        ("a" * 64, "longer than 63"),
        ("int", "C keyword"),
        ("while", "C keyword"),
    ],
)
def test_other_identifiers_are_a_spec_error_naming_the_field(name, reason):
    with pytest.raises(SpecError, match=reason) as caught:
        c_identifier(name, "arm.params.name")
    assert caught.value.field == "arm.params.name"


# --------------------------------------------------------------------------- Makefile and CMake
@pytest.mark.parametrize("text", [t for t in HOSTILE if t] + ["a b", "a#b", "a:b", "a=b", "a%b", "-n", ".x", ""])
def test_a_makefile_refuses_every_word_outside_the_allow_list(text):
    with pytest.raises(SpecError, match="cannot be a Makefile name") as caught:
        make_word(text, "stem")
    assert caught.value.field == "stem"


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make")
def test_makefile_words_of_the_allow_list_are_read_literally_by_make(tmp_path):
    words = ["optikin_fk", "optikin_fk.c", "liboptikin_fk.a", "a+b-c.d", "_1"]
    rules = "".join(f"\t@printf '%s\\n' {make_word(w, 'stem')}\n" for w in words)
    (tmp_path / "Makefile").write_text(f"all:\n{rules}")
    run = subprocess.run(["make", "-s", "-C", str(tmp_path)], capture_output=True, text=True, timeout=60, check=True)
    assert run.stdout.split() == words


@needs_cmake
def test_cmake_values_hold_exactly_the_text(tmp_path):
    texts = [t for t in HOSTILE if t.isascii() and t.isprintable()] + ["optikin_fk.c"]
    script = "".join(
        f'set(V{i} {cmake_value(t, "stem")})\nfile(WRITE "{tmp_path}/value{i}.txt" "${{V{i}}}")\n'
        for i, t in enumerate(texts)
    )
    (tmp_path / "values.cmake").write_text(script, encoding="ascii")
    run = subprocess.run(["cmake", "-P", str(tmp_path / "values.cmake")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert [(tmp_path / f"value{i}.txt").read_text() for i in range(len(texts))] == texts
    assert not (tmp_path / "pwned").exists() and not Path("pwned").exists()


@pytest.mark.parametrize("text", ["a\nb", "tab\there", "\r", "\x00", "\u00e9"])
def test_cmake_values_refuse_control_characters_and_non_ascii(text):
    with pytest.raises(SpecError, match="printable ASCII only") as caught:
        cmake_value(text, "stem")
    assert caught.value.field == "stem"


# --------------------------------------------------------------------------- --out
def refused(capsys, out: str) -> str:
    """``optikin export ... --out out`` is exit 2 with one line on stderr and nothing on stdout; that line."""
    assert main(["export", PROBLEM, "--what", "fk", "--out", out]) == EXIT_BAD_INPUT
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("optikin: error: "), captured.err
    return lines[0]


@pytest.mark.parametrize("out", ["", "   "])
def test_an_empty_out_is_refused_and_nothing_is_written_here(tmp_path, monkeypatch, capsys, out):
    monkeypatch.chdir(tmp_path)
    assert "--out: an empty output folder is not accepted" in refused(capsys, out)
    assert list(tmp_path.iterdir()) == []


def test_an_out_that_is_a_file_or_under_one_is_refused(tmp_path, capsys):
    (tmp_path / "file").write_text("mine")
    before = snapshot(tmp_path)
    assert f"{tmp_path / 'file'}: not a folder" in refused(capsys, str(tmp_path / "file"))
    assert f"{tmp_path / 'file'}: not a folder" in refused(capsys, str(tmp_path / "file" / "sub"))
    assert snapshot(tmp_path) == before and (tmp_path / "file").read_text() == "mine"


def test_a_dangling_symlink_is_refused_and_its_target_not_created(tmp_path, capsys):
    (tmp_path / "link").symlink_to(tmp_path / "missing")
    before = snapshot(tmp_path)
    for out in ("link", "link/sub"):
        assert "a symlink to nothing" in refused(capsys, str(tmp_path / out))
    assert snapshot(tmp_path) == before and not (tmp_path / "missing").exists()


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc")
def test_an_out_that_cannot_be_created_is_refused(capsys):
    assert "/proc/x" in refused(capsys, "/proc/x")
    assert not Path("/proc/x").exists()


def test_a_symlink_where_a_file_goes_is_refused_and_its_target_kept(tmp_path, capsys):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.write_text("mine")
    (out / "Makefile").symlink_to(victim)
    (out / "main.c").mkdir()
    before = snapshot(tmp_path)
    assert "a symlink or folder is where the export writes a file" in refused(capsys, str(out))
    (out / "Makefile").unlink()
    assert "main.c: a symlink or folder" in refused(capsys, str(out))
    before.discard(str(out / "Makefile"))
    assert snapshot(tmp_path) == before and victim.read_text() == "mine"


def test_a_failed_write_leaves_nothing(tmp_path, monkeypatch, capsys):
    """A full disk at the third file: no file, no temporary, not the folder the export created."""
    real = Path.write_text

    def full(self, *args, **kwargs):
        if self.name.startswith(".main.c."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", full)
    assert "No space left on device" in refused(capsys, str(tmp_path / "new" / "out"))
    assert list(tmp_path.iterdir()) == []
    existing = tmp_path / "existing"
    existing.mkdir()
    assert "No space left on device" in refused(capsys, str(existing))
    assert list(existing.iterdir()) == []


def test_the_api_refuses_the_same_folders(tmp_path):
    (tmp_path / "file").write_text("mine")
    with pytest.raises(OutputError, match="not a folder"):
        export(PROBLEM, "fk", tmp_path / "file")
    with pytest.raises(OutputError, match="empty output folder"):
        export(PROBLEM, "fk", "")


def test_codegen_refuses_names_that_are_not_identifiers():
    x = ca.SX.sym("x", 2)
    with pytest.raises(SpecError, match="compiled code: input or output name of f"):
        codegen._source(ca.Function("f", [x], [x], ["q*/ int evil; /*"], ["y"]))
    with pytest.raises(SpecError, match="library name"):
        codegen.source_library("../evil", "int x;", ("-O0",))
