"""
No class is cut into mixins with one host: a class that is one concept stays whole.

A mixin is a base class that another class mixes in beside other bases. With one
host it splits a file, not a class: the object keeps the same methods and state,
now declared in one file and used in others, out of sight of any checker. Where a
class holds two concepts, compose parts that own their data; where it holds one, let
it be long (rclpy's ``Node``). A mixin with several hosts (the testing API's
``WorldVerbs`` serves both harnesses) is real reuse. Read with ``ast``: imports
nothing, part of the fast tier. The check is run on a small package written for
the purpose too, to prove it finds what it looks for.
"""

import ast
from collections import defaultdict
from pathlib import Path
from typing import Dict, List, Tuple

from common import REPO


def _base_name(node: ast.expr) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ''


def single_host_mixins(package: Path) -> List[str]:
    """
    Return 'Base (file) mixed only into Host (file)' for each single-host mixin.

    A class of the package with no ``__init__`` of its own (it works on its host's
    state) counts as mixed in when a class of the package has it among two or more
    bases; it is a single-host mixin when no other class of the package derives from
    it. A base that builds its own state (``RosHarness``, used on its own too),
    exceptions and typing Protocols are not mixins.
    """
    classes: Dict[str, str] = {}
    constructs: Dict[str, bool] = {}
    bases_of: Dict[Tuple[str, str], List[str]] = {}
    for path in sorted(package.rglob('*.py')):
        tree = ast.parse(path.read_text(encoding='utf-8'), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                where = str(path.relative_to(package.parent))
                classes.setdefault(node.name, where)
                constructs[node.name] = constructs.get(node.name, False) or any(
                    isinstance(item, ast.FunctionDef) and item.name == '__init__'
                    for item in node.body)
                bases_of[(node.name, where)] = [_base_name(b) for b in node.bases]
    hosts: Dict[str, List[Tuple[str, str, int]]] = defaultdict(list)
    for (name, where), bases in bases_of.items():
        ours = [base for base in bases if base in classes]
        for base in ours:
            hosts[base].append((name, where, len(bases)))
    found = []
    for base, derived in sorted(hosts.items()):
        if base.endswith(('Error', 'Exception')) or constructs[base] or 'Protocol' in \
                bases_of.get((base, classes[base]), []):
            continue
        if len(derived) == 1 and derived[0][2] > 1:
            host, where, _ = derived[0]
            found.append(f'{base} ({classes[base]}) mixed only into {host} ({where})')
    return found


def test_no_class_is_mixed_into_a_single_host():
    """Every mixin of r2d2_sim has at least two hosts."""
    assert single_host_mixins(Path(REPO) / 'r2d2_sim') == []


def test_the_check_finds_a_single_host_mixin(tmp_path):
    """Verbs mixed into one Target are found; a mixin of two hosts, errors, a built base not."""
    package = tmp_path / 'fakepkg'
    package.mkdir()
    (package / 'verbs.py').write_text(
        'class EntityVerbs:\n    pass\n\n\nclass Shared:\n    pass\n')
    (package / 'target.py').write_text(
        'from fakepkg.verbs import EntityVerbs, Shared\n\n\n'
        'class Base:\n    def __init__(self):\n        self.x = 1\n\n\n'
        'class FakeError(Exception):\n    pass\n\n\n'
        'class OtherError(FakeError, ValueError):\n    pass\n\n\n'
        'class Target(Base, EntityVerbs, Shared):\n    pass\n\n\n'

        'class Child(Shared):\n    pass\n')
    assert single_host_mixins(package) == [
        'EntityVerbs (fakepkg/verbs.py) mixed only into Target (fakepkg/target.py)']
