"""Text that reaches the files ``optikin export`` writes, one function per context.

Every piece of a generated C file, header, ``Makefile`` or ``CMakeLists.txt`` that optikin did not
write as a constant goes through one of these:

:func:`c_comment`
    inside ``/* ... */``: printable ASCII only, never ``*``, ``/``, ``\\`` or ``?`` (so no ``*/``
    or ``/*`` can form, not even with the template's text around it, and no trigraph or line
    splice), each other character replaced by ``_``; :func:`problem_comment` names a problem by
    its file stem only.
:func:`c_string`
    a C string literal: quotes, backslashes and ``?`` escaped, every byte outside printable ASCII
    (newlines, UTF-8 of non-ASCII text) as a three-digit octal escape.
:func:`c_identifier`
    an identifier from the allow-list ``[A-Za-z_][A-Za-z0-9_]*`` (at most 63 characters, not a C
    keyword), else a :class:`~optikin.errors.SpecError` naming the field.
:func:`make_word`
    a file or target name in a ``Makefile``: make cannot quote a target, so the word is one of the
    allow-list ``[A-Za-z0-9_][A-Za-z0-9_.+-]*`` that make and the shell both read literally (no
    option, no hidden file), else a ``SpecError``.
:func:`cmake_value`
    a CMake quoted argument: ``\\``, ``"`` and ``$`` escaped (one argument, whatever ``;`` it holds,
    with no variable reference or generator expression), control characters and non-ASCII refused.
"""

from __future__ import annotations

import re
from pathlib import PurePath

from optikin.errors import SpecError

WHERE = "optikin export"
"""What a :class:`~optikin.errors.SpecError` of this module names when no file is at fault."""

MAX_IDENTIFIER = 63
"""Longest identifier accepted: the significant length C99 guarantees for internal names."""

C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int long "
    "register restrict return short signed sizeof static struct switch typedef union unsigned void volatile while "
    "_Bool _Complex _Imaginary".split()
)
"""The keywords of C99, which are not identifiers."""

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_MAKE_WORD = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.+-]*")
_COMMENT_UNSAFE = re.compile(r"[^ -~]|[*/\\?]")
_STRING_PLAIN = frozenset(chr(c) for c in range(0x20, 0x7F)) - set('"\\?')
_CMAKE_ESCAPES = {"\\": "\\\\", '"': '\\"', "$": "\\$"}


def c_comment(text: str) -> str:
    """``text`` made safe inside a C block comment: each character outside printable ASCII or in ``*/\\?`` is ``_``.

    The result has no newline, cannot open or close a comment whatever surrounds it, and holds no
    trigraph (``??/`` would be a backslash) or line splice.
    """
    return _COMMENT_UNSAFE.sub("_", str(text))


def problem_comment(problem: str) -> str:
    """How generated comments name problem ``problem`` (a name or a path): its file stem, as :func:`c_comment`.

    The stem is what :func:`optikin.spec.load_problem` checks the file's ``name`` field against; the
    folders above it, which an unpacked archive may name at will, never reach a generated file.
    """
    return c_comment(PurePath(str(problem)).stem)


def c_string(text: str) -> str:
    """The C string literal (with its quotes) whose bytes are the UTF-8 encoding of ``text``."""
    out = []
    for byte in str(text).encode("utf-8"):
        char = chr(byte)
        out.append(char if char in _STRING_PLAIN else f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def c_identifier(text: str, field: str, where: str = WHERE) -> str:
    """``text`` if it is a C identifier of the allow-list (module docstring).

    Parameters
    ----------
    text:
        The would-be identifier.
    field:
        What it comes from (a field, an arm's or a Function's name), for the error.
    where:
        The file (or command) at fault, for the error.

    Raises
    ------
    SpecError
        ``text`` is not a string, does not match ``[A-Za-z_][A-Za-z0-9_]*``, is longer than
        :data:`MAX_IDENTIFIER` or is a C keyword.
    """
    if not isinstance(text, str) or not _IDENTIFIER.fullmatch(text):
        raise SpecError(where, field, f"{text!r} is not a C identifier (ASCII letters, digits, underscores)")
    if len(text) > MAX_IDENTIFIER:
        raise SpecError(where, field, f"{text!r} is longer than {MAX_IDENTIFIER} characters")
    if text in C_KEYWORDS:
        raise SpecError(where, field, f"{text!r} is a C keyword")
    return text


def make_word(text: str, field: str, where: str = WHERE) -> str:
    """``text`` if a ``Makefile`` may hold it as a file or target name (module docstring).

    Raises
    ------
    SpecError
        ``text`` holds anything else (``$``, a backtick, a quote, a space, ``#``, ``:``, a newline...).
    """
    if not isinstance(text, str) or not _MAKE_WORD.fullmatch(text):
        raise SpecError(where, field, f"{text!r} cannot be a Makefile name (letters, digits, _ . + -, not first . + -)")
    return text


def cmake_value(text: str, field: str, where: str = WHERE) -> str:
    """The CMake quoted argument (with its quotes) whose value is ``text``.

    Raises
    ------
    SpecError
        ``text`` holds a character outside printable ASCII (a newline, a tab, non-ASCII).
    """
    text = str(text)
    bad = [c for c in text if not " " <= c <= "~"]
    if bad:
        raise SpecError(where, field, f"{text!r} holds {bad[0]!r}: a CMake value takes printable ASCII only")
    return '"' + "".join(_CMAKE_ESCAPES.get(c, c) for c in text) + '"'
