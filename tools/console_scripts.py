#!/usr/bin/env python3
"""
Write setup.py's executables into a venv's ``bin/`` as wrappers that run this checkout.

    python tools/console_scripts.py VENV

``pip install .`` puts ``sim_node``, ``sim_conformance``, ``demo``, ``drive`` and
``replay`` on PATH; ``./run.sh`` installs nothing (it runs the source tree, on
PYTHONPATH), so it calls this on its ``.venv``: each ``console_scripts`` entry
of setup.py becomes ``VENV/bin/NAME``, a shell script that calls the entry
point (``module:function``) as pip's script would (``sys.argv[0]`` the
script), with the checkout that holds the venv (``bin/../..``, as the script
was reached) first on PYTHONPATH and ROS discovery kept on this host unless
set, as ``./run.sh`` does. A file there that is not such a wrapper (a pip
install's own script) is left alone, and a wrapper is written only when its
text changed. Standard library only, so ``python -S`` runs it in milliseconds.
"""

import ast
import os
import sys
from typing import List, Optional, Tuple

MARKER = '# written by ./run.sh (tools/console_scripts.py)'
SETUP_PY = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'setup.py')

WRAPPER = '''#!/bin/sh
{marker}: {name}, the entry point {target}
# of the checkout this venv is in, run as `pip install .` would run it.
bin=$(dirname -- "$0")
root=$(CDPATH= cd "$bin/../.." && pwd)
export PYTHONPATH="$root${{PYTHONPATH:+:$PYTHONPATH}}"
export ROS_AUTOMATIC_DISCOVERY_RANGE="${{ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}}"
exec "$bin/python" -c 'import sys; sys.argv = sys.argv[1:]; from {module} import {function}; \
sys.exit({function}())' "$0" "$@"
'''


def console_scripts(setup_py: str = SETUP_PY) -> List[Tuple[str, str, str]]:
    """Return setup.py's console scripts as (name, module, function), read without running it."""
    with open(setup_py, encoding='utf-8') as handle:
        tree = ast.parse(handle.read())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup':
            for keyword in node.keywords:
                if keyword.arg == 'entry_points' and isinstance(keyword.value, ast.Dict):
                    # Only the console_scripts entry is read: the others (plugins'
                    # groups, a **mapping read from a file) need not be literals.
                    for key, value in zip(keyword.value.keys, keyword.value.values):
                        if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                            return [_parse(entry) for entry in ast.literal_eval(value)]
    return []


def _parse(entry: str) -> Tuple[str, str, str]:
    name, _, target = (part.strip() for part in entry.partition('='))
    module, _, function = target.partition(':')
    return name, module.strip(), function.strip()


def write_wrappers(venv: str, setup_py: str = SETUP_PY) -> List[str]:
    """Write (or keep) a wrapper in ``venv/bin`` for every console script; return their paths."""
    written = []
    for name, module, function in console_scripts(setup_py):
        path = os.path.join(venv, 'bin', name)
        text = WRAPPER.format(marker=MARKER, name=name, target=f'{module}:{function}',
                              module=module, function=function)
        now = _read(path)
        if now is not None and not now.startswith(f'#!/bin/sh\n{MARKER}'):
            continue  # another's script (pip's): left alone
        if now != text:
            temporary = f'{path}.writing'
            with open(temporary, 'w', encoding='utf-8') as handle:
                handle.write(text)
            os.chmod(temporary, 0o755)
            os.replace(temporary, path)
        written.append(path)
    return written


def _read(path: str) -> Optional[str]:
    """Return the text of the file at ``path``; None when there is none."""
    if not os.path.lexists(path):
        return None
    try:
        with open(path, 'rb') as handle:
            return handle.read(1 << 16).decode('utf-8', errors='replace')
    except OSError:
        return ''  # there, unreadable: not ours to replace


def main() -> int:
    """Write the wrappers into the venv named on the command line."""
    if len(sys.argv) != 2:
        print('usage: console_scripts.py VENV', file=sys.stderr)
        return 2
    write_wrappers(sys.argv[1])
    return 0


if __name__ == '__main__':
    sys.exit(main())
