"""
Write the files made from the package's tables: ``./run.sh generate``.

``python -m mover6_control.tools.generate ROOT`` writes ``config/<node>.yaml`` and
``docs/parameters.md`` (``mover6_control.parameter_files``, from ``mover6_control.parameters``)
and the arm's collision model ``mover6_control/collision/body_model.py`` (derived from the
maker's meshes, ``tools.derive_collision``) under the repository ``ROOT``; with ``--check``
it writes nothing and lists the files that differ from what it would write (exit 1).
The files are committed; a test checks them.
"""

import argparse
import os
import sys
from typing import Optional

from mover6_control import parameter_files
from mover6_control.tools import derive_collision


def generated_files() -> dict:
    """Return {path relative to the repository: text} of every generated file."""
    return {**parameter_files.generated_files(), **derive_collision.generated_files()}


def _text(root: str, path: str) -> Optional[str]:
    try:
        with open(os.path.join(root, path)) as f:
            return f.read()
    except FileNotFoundError:
        return None


def differing(root: str) -> list[str]:
    """Return the generated files under ``root`` whose text is not the generator's output."""
    return [path for path, text in generated_files().items() if _text(root, path) != text]


def write(root: str) -> list[str]:
    """Write every generated file under ``root``; return the paths that changed."""
    files = generated_files()
    changed = [path for path, text in files.items() if _text(root, path) != text]
    for path, text in files.items():
        if path in changed:
            with open(os.path.join(root, path), 'w') as f:
                f.write(text)
    return changed


def main(argv: Optional[list[str]] = None) -> int:
    """Write the generated files (or, with --check, list those that differ)."""
    parser = argparse.ArgumentParser(prog='generate', description=__doc__.strip().split('\n')[0])
    parser.add_argument('root', help='the repository (the folder of run.sh)')
    parser.add_argument('--check', action='store_true',
                        help='write nothing; list the files that differ and exit 1 if any')
    args = parser.parse_args(argv)
    if args.check:
        stale = differing(args.root)
        for path in stale:
            print(f'generate: {path} is not the generated text (./run.sh generate)')
        return 1 if stale else 0
    for path in write(args.root):
        print(f'generate: wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
