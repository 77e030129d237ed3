"""
The parameter table written out for people: ``sim_node --help`` and ``docs/parameters.md``.

No ROS here, only the standard library. Both come from
:data:`~r2d2_sim.sim.settings.table.PARAMETERS`, as the validation and the ROS
declarations do, so neither can drift from the table: ``--help`` is built at
each call, and a test compares ``docs/parameters.md`` with
:func:`render_parameter_reference`. To write the page after changing the table::

    python -m r2d2_sim.sim.settings.reference docs/parameters.md
"""

import json
import sys
import textwrap
from typing import List, Optional, Sequence

from r2d2_sim.sim.settings.table import Parameter, PARAMETERS

__all__ = ['parameter_help', 'render_parameter_reference', 'main']


def _number(spec: Parameter, value: float) -> str:
    return str(int(value)) if spec.ros_type.startswith('integer') else f'{value:g}'


def _choices(spec: Parameter) -> Optional[str]:
    """Return "one of ..." for a parameter read from a fixed list, else None."""
    choices = getattr(spec.read, 'choices', None)
    return None if choices is None else 'one of ' + ', '.join(str(c) for c in choices)


def _range(spec: Parameter) -> Optional[str]:
    """Return the range of a bounded number with its unit and what 0 means, else None."""
    bounds = spec.bounds
    if bounds is None:
        return None
    unit = f' {bounds.unit}' if bounds.unit else ''
    zero = f' or 0 ({bounds.zero})' if bounds.zero else ''
    if spec.ros_type.startswith('integer'):
        return f'[{_number(spec, bounds.low)}, {_number(spec, bounds.high)}]{unit}{zero}'
    return f'{bounds.text()}{unit}{zero}'


def parameter_help(width: int = 79) -> str:
    """
    Return every parameter as ``--help`` lists it: name, type, default, range, description.

    Defaults are written as JSON, which ROS reads as YAML, so each can be
    typed after ``-p name:=`` as shown. "per robot" marks what each robot
    listed in ``robots`` may set for itself (``-p NAME.parameter:=``).
    """
    lines = []
    for spec in PARAMETERS:
        facts = [spec.ros_type, f'default {json.dumps(spec.default)}']
        choices, bounds = _choices(spec), _range(spec)
        if choices is not None:
            facts.append(choices)
        if bounds is not None:
            facts.append(f'range {bounds}')
        if spec.per_robot:
            facts.append('per robot')
        lines += textwrap.wrap(f'{spec.name}: {"; ".join(facts)}', width, initial_indent='  ',
                               subsequent_indent=' ' * 6, break_long_words=False,
                               break_on_hyphens=False)
        lines += textwrap.wrap(spec.description, width, initial_indent=' ' * 6,
                               subsequent_indent=' ' * 6, break_on_hyphens=False)
    return '\n'.join(lines) + '\n'


_REFERENCE_HEAD = """\
<!-- Generated from PARAMETERS in r2d2_sim/sim/settings/table.py by
     python -m r2d2_sim.sim.settings.reference docs/parameters.md
     Edit the table, not this page: a test fails when the two differ. -->

# Parameters

Every parameter of `sim_node`, from the one table that the node's validation, its typed
ROS declarations and `sim_node --help` also come from
([`r2d2_sim/sim/settings/table.py`](../r2d2_sim/sim/settings/table.py)).

All are read-only after start-up and declared with their type (and most numbers with their
range), so `ros2 param describe` shows them, and `ros2 param dump` or rqt read them all at
once (an empty list, `extra_models`' default, reads back as an empty string array). Frame
ids that would break the TF tree are refused: a leading `/`, characters tf2 rejects, or two
of the robot's frames alike (`odom_frame_id:=base_link`). Invalid values, and physical
values outside a plausible range, stop the node with one line on stderr
(`r2d2_sim: error: parameter wheel_radius must be in [0.001, 10] m (derive it from the URDF
with 0), got 1e+308`) and exit code 2. Integers are accepted where a real number is
expected.

Defaults are written as JSON, which ROS reads as YAML, so each can be typed after
`-p name:=` as shown. A range's "or 0 (...)" says what 0 means where 0 lies outside the
range. *Per robot*: each robot listed in `robots` may set its own value as
`NAME.parameter` ([several robots](several-robots.md)); the others are the world's, one
for all robots.

"""

_REFERENCE_TAIL = (
    '\n## A listed robot\'s own settings\n\n'
    '| name | default | meaning |\n'
    '|---|---|---|\n'
    '| `NAME.<parameter>` | the world\'s value | robot `NAME`\'s own setting of any per-robot '
    'parameter above (its description, drive, frames, sensors, `initial_pose`...); for a '
    'name `robots` does not list, ignored with a warning |\n'
    '| `NAME.namespace` | `NAME` | robot `NAME`\'s namespace: absolute, or relative to the '
    'simulator\'s |\n')


def _cell(text: str) -> str:
    return text.replace('|', '\\|')


def render_parameter_reference(parameters: Sequence[Parameter] = PARAMETERS) -> str:
    """
    Return ``docs/parameters.md``: the table as Markdown, one row per parameter, in its order.

    Columns: name, ROS type, default (JSON, as ``-p name:=`` takes it), range
    or choices, per robot, description. ``parameters`` is there so a test
    can render a changed table.
    """
    rows: List[str] = [
        '| name | type | default | range or choices | per robot | description |',
        '|---|---|---|---|---|---|']
    for spec in parameters:
        allowed = _choices(spec) or _range(spec) or ''
        cells = (f'`{spec.name}`', spec.ros_type, f'`{json.dumps(spec.default)}`', allowed,
                 'yes' if spec.per_robot else '', spec.description)
        rows.append('| ' + ' | '.join(_cell(c) for c in cells) + ' |')
    return _REFERENCE_HEAD + '\n'.join(rows) + '\n' + _REFERENCE_TAIL


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Write the reference to the file named (``docs/parameters.md``), or print it."""
    args = sys.argv[1:] if argv is None else list(argv)
    text = render_parameter_reference()
    if not args:
        sys.stdout.write(text)
        return 0
    with open(args[0], 'w', encoding='utf-8') as out:
        out.write(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
