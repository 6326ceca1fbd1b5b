"""
YAML read with the line of every value: the node tree of ``yaml.compose``, as small values.

A ``Marked`` is a value (a dict of str to ``Marked``, a list of ``Marked``, or a scalar) with
the 1-based line where it starts, so every error of a file can name its line; the value of a
mapping's key is marked with the key's line (``steps:`` above its list names that line).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mover6_control.programs.program_error import ProgramError
import yaml


@dataclass(frozen=True)
class Marked:
    """A YAML value and the line (1-based) where it starts."""

    value: Any
    line: int

    def plain(self) -> Any:
        """Return the value without marks (dicts, lists and scalars)."""
        if isinstance(self.value, dict):
            return {k: v.plain() for k, v in self.value.items()}
        if isinstance(self.value, list):
            return [v.plain() for v in self.value]
        return self.value


def _convert(node, constructor, path):
    line = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        out = {}
        for key_node, value_node in node.value:
            key = constructor.construct_object(key_node, deep=True)
            if not isinstance(key, str):
                raise ProgramError(path, key_node.start_mark.line + 1,
                                   f'a key must be a name, got {key!r}', 'syntax')
            if key in out:
                raise ProgramError(path, key_node.start_mark.line + 1,
                                   f'key "{key}" given twice', 'syntax')
            value = _convert(value_node, constructor, path)
            out[key] = Marked(value.value, key_node.start_mark.line + 1)
        return Marked(out, line)
    if isinstance(node, yaml.SequenceNode):
        return Marked([_convert(v, constructor, path) for v in node.value], line)
    return Marked(constructor.construct_object(node, deep=True), line)


def load_marked(text: str, path: str) -> Marked:
    """
    Return the document of ``text`` as a ``Marked`` tree; ``path`` names the file in errors.

    Raises ``ProgramError`` (code 'syntax') for text that is no YAML or an empty document.
    """
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
        if node is None:
            raise ProgramError(path, 0, 'the file is empty', 'syntax')
        return _convert(node, yaml.constructor.SafeConstructor(), path)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        line = mark.line + 1 if mark is not None else 0
        raise ProgramError(path, line, f'not YAML: {err.problem or err}', 'syntax') from None
    except yaml.YAMLError as err:
        raise ProgramError(path, 0, f'not YAML: {err}', 'syntax') from None


def read_marked(path: str) -> Marked:
    """Return the file at ``path`` as a ``Marked`` tree (``load_marked``)."""
    try:
        with open(path, encoding='utf-8') as f:
            text = f.read()
    except OSError as err:
        raise ProgramError(path, 0, f'cannot read the file: {err.strerror}', 'syntax') from None
    return load_marked(text, path)
