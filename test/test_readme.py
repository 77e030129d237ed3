"""The README's example test for users runs as written."""

import os
import re

from conftest import REPO


def test_readme_example_test_passes():
    """Extract the README's pytest example and run its test function."""
    text = open(os.path.join(REPO, 'README.md'), encoding='utf-8').read()
    section = text.split('## Testing your own code', 1)[1]
    code = re.search(r'```python\n(.*?)```', section, re.S).group(1)
    namespace = {}
    exec(compile(code, 'README.md', 'exec'), namespace)
    tests = [f for name, f in namespace.items() if name.startswith('test_')]
    assert len(tests) == 1
    tests[0]()
