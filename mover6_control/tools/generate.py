"""
Write the files made from the package's tables: ``./run.sh generate``.

``python -m mover6_control.tools.generate ROOT`` writes ``config/<node>.yaml`` and
``docs/parameters.md`` (``mover6_control.parameter_files``, from ``mover6_control.parameters``)
and the generated MoveIt files ``config/moveit/`` (``mover6_control.tools.moveit_config``) and
the arm's collision model ``mover6_control/collision/body_model.py`` (derived from the maker's
meshes, ``tools.derive_collision``) under the repository ``ROOT``; with ``--check`` it writes
nothing and lists the files that differ from what it would write (exit 1). The files are
committed; a test checks them.
"""

import argparse
import os
import sys
from typing import Optional

from mover6_control import parameter_files
from mover6_control.tools import derive_collision, moveit_config


def generated_files() -> dict[str, str]:
    """Return {path under the repository: text} of every generated file."""
    files = dict(parameter_files.generated_files())
    files.update(derive_collision.generated_files())
    files.update({f'config/moveit/{name}': text
                  for name, text in moveit_config.generated_files().items()})
    return files


def differing(root: str, files: Optional[dict[str, str]] = None) -> list[str]:
    """Return the generated files under ``root`` whose text is not the generator's output."""
    out = []
    for path, text in (generated_files() if files is None else files).items():
        try:
            with open(os.path.join(root, path)) as f:
                if f.read() == text:
                    continue
        except FileNotFoundError:
            pass
        out.append(path)
    return out


def write(root: str) -> list[str]:
    """Write every generated file under ``root``; return the paths that changed."""
    files = generated_files()
    changed = differing(root, files)
    for path in changed:
        os.makedirs(os.path.dirname(os.path.join(root, path)), exist_ok=True)
        with open(os.path.join(root, path), 'w') as f:
            f.write(files[path])
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
