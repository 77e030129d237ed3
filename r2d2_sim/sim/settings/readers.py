"""
Readers for the parameter table: a raw ROS value in, a valid value out, or one ConfigError line.

No ROS here. Each reader takes the parameter's name (for the message) and
the raw value as ROS hands it over, and returns the value in the type and
units of :class:`~r2d2_sim.sim.settings.table.SimConfig`; :class:`Bounds` then holds
a number to its plausible range. Frame ids are held to what tf2 and REP-105
accept.
"""

from decimal import Decimal, ROUND_CEILING, ROUND_FLOOR
import math
import re
from typing import Any, Callable, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.errors import RefusedError, SetupError
from r2d2_sim.sim.tags import check_tags

__all__ = ['ConfigError', 'Bounds', 'bound_text', 'number', 'positive', 'non_negative', 'limit',
           'field_of_view', 'ratio', 'boolean', 'string', 'frame', 'frame_prefix', 'joint_names',
           'integer', 'choice', 'numbers', 'optional_numbers', 'variances', 'extra_models',
           'robot_names', 'namespace', 'tags', 'directories', 'ROBOT_NAME',
           'MAX_NAMESPACE_LENGTH']


class ConfigError(SetupError, ValueError):
    """A parameter value the simulator cannot run with."""


class Bounds(NamedTuple):
    """
    The plausible range of a number, with its unit for messages.

    ``zero`` names what 0 means when 0 is allowed outside the range ("derive
    it from the URDF", "no limit"); None when 0 is just a value to check.
    """

    low: float
    high: float
    unit: str = ''
    zero: Optional[str] = None

    def text(self) -> str:
        """Return the range as messages and the docs print it: ``[low, high]``, each accepted."""
        return f'[{bound_text(self.low, upward=True)}, {bound_text(self.high, upward=False)}]'

    def check(self, name: str, value: float) -> float:
        """Return ``value`` if it is in range (or an allowed 0), else raise ConfigError."""
        if value == 0.0 and self.zero is not None:
            return value
        if not self.low <= value <= self.high:
            unit = f' {self.unit}' if self.unit else ''
            zero = f' ({self.zero} with 0)' if self.zero else ''
            got = f'{value:g}'
            if self.low <= float(got) <= self.high:  # 6 digits would round it into the range
                got = repr(value)
            raise ConfigError(f'parameter {name} must be in {self.text()}{unit}{zero}, got {got}')
        return value


def bound_text(value: float, upward: bool) -> str:
    """
    Return a bound as ``%g`` writes it, rounded toward the inside of its range.

    ``%g`` rounds to 6 digits, which can put a bound outside its own range
    (pi / 2 printed as 1.5708 is refused by the range it names): a low bound
    (``upward``) is rounded up, a high one down, so the number printed is accepted.
    """
    text = f'{value:g}'
    if (float(text) >= value) if upward else (float(text) <= value):
        return text
    exact = Decimal(value)
    sixth_digit = Decimal(1).scaleb(exact.adjusted() - 5)
    inside = exact.quantize(sixth_digit, rounding=ROUND_CEILING if upward else ROUND_FLOOR)
    return f'{float(inside):g}'


def number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'parameter {name} must be a number, got {value!r}')
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f'parameter {name} must be finite, got {value}')
    return value


def positive(name: str, value: Any) -> float:
    value = number(name, value)
    if value <= 0.0:
        raise ConfigError(f'parameter {name} must be > 0, got {value}')
    return value


def non_negative(name: str, value: Any) -> float:
    value = number(name, value)
    if value < 0.0:
        raise ConfigError(f'parameter {name} must be >= 0, got {value}')
    return value


def limit(name: str, value: Any) -> float:
    """Read a limit where 0 means none: math.inf."""
    return non_negative(name, value) or math.inf


def field_of_view(name: str, value: Any) -> float:
    value = positive(name, value)
    if value >= 180.0:
        raise ConfigError(f'parameter {name} must be below 180 degrees, got {value}')
    return value


def ratio(name: str, value: Any) -> float:
    value = positive(name, value)
    if value > 1.0:
        raise ConfigError(f'parameter {name} must be in (0, 1], got {value}')
    return value


def boolean(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(f'parameter {name} must be true or false, got {value!r}')
    return value


def string(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise ConfigError(f'parameter {name} must be a string, got {value!r}')
    return value


# A frame id: names of letters, digits, '_', '-' and '.', joined by single '/'.
# tf2 refuses a leading '/' (ROS 1's tf_prefix style) and an empty id; spaces,
# quotes, ':' and the like break YAML files, command lines and tools that echo
# frames, so they are refused here too.
_FRAME_PART = r'[A-Za-z0-9_.\-]+'
_FRAME_ID = re.compile(rf'{_FRAME_PART}(?:/{_FRAME_PART})*')
_FRAME_PREFIX = re.compile(rf'(?:{_FRAME_PART}/)*(?:{_FRAME_PART})?')


def _frame_syntax(name: str, value: str, pattern: 're.Pattern', what: str) -> str:
    if value.startswith('/'):
        raise ConfigError(f'parameter {name} must not start with \'/\' (tf2 refuses such '
                          f'frame ids), got {value!r}; use {value.lstrip("/")!r}')
    if not pattern.fullmatch(value):
        raise ConfigError(f'parameter {name} must be {what} (letters, digits, _ - . '
                          f'and single / between names, no spaces), got {value!r}')
    return value


def frame(name: str, value: Any) -> str:
    value = string(name, value)
    if not value.strip():
        raise ConfigError(f'parameter {name} must not be empty, got {value!r}')
    return _frame_syntax(name, value, _FRAME_ID, 'a tf2 frame id')


def frame_prefix(name: str, value: Any) -> str:
    return _frame_syntax(name, string(name, value), _FRAME_PREFIX,
                         'empty or a frame id prefix such as robot1/')


def _is_string_list(value: Any) -> bool:
    return (isinstance(value, (list, tuple))
            and all(isinstance(v, str) for v in value))


def joint_names(name: str, value: Any) -> Tuple[str, ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter {name} must be a list of joint names, got {value!r}')
    names = tuple(value)
    if len(set(names)) != len(names):
        raise ConfigError(f'parameter {name} lists a joint twice: {list(names)}')
    return names


def tags(name: str, value: Any) -> Tuple[str, ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter {name} must be a list of tags, got {value!r}')
    try:
        return check_tags(value, f'parameter {name}')
    except RefusedError as exc:
        raise ConfigError(exc.message) from None


def directories(name: str, value: Any) -> Tuple[str, ...]:
    if not _is_string_list(value) or not all(value):
        raise ConfigError(f'parameter {name} must be a list of directories (paths, file:// or '
                          f'package:// URIs), got {value!r}')
    return tuple(value)


def integer(name: str, value: Any) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or (isinstance(value, float) and not value.is_integer())):
        raise ConfigError(f'parameter {name} must be an integer, got {value!r}')
    return int(value)


class _Choice:
    """Read one of ``choices``, which it shows to --help and docs/parameters.md (reference)."""

    def __init__(self, choices: Sequence[Any]) -> None:
        self.choices = tuple(choices)

    def __call__(self, name: str, value: Any) -> Any:
        if isinstance(value, bool) or value not in self.choices:
            # ROS parameter files read a bare y, n, yes, on... as booleans.
            hint = ' (quote the value in YAML files)' if isinstance(value, bool) else ''
            raise ConfigError(f'parameter {name} must be one of '
                              f'{", ".join(str(c) for c in self.choices)}; got {value!r}{hint}')
        return value


def choice(choices: Sequence[Any]) -> Callable[[str, Any], Any]:
    return _Choice(choices)


def numbers(length: int) -> Callable[[str, Any], Tuple[float, ...]]:
    def read(name: str, value: Any) -> Tuple[float, ...]:
        if (isinstance(value, (str, bytes)) or not hasattr(value, '__len__')
                or len(value) != length):
            raise ConfigError(
                f'parameter {name} must be a list of {length} numbers, got {value!r}')
        return tuple(number(name, v) for v in value)
    return read


def optional_numbers(length: int) -> Callable[[str, Any], Tuple[float, ...]]:
    """Read an empty list (none) or a list of ``length`` numbers."""
    exact = numbers(length)

    def read(name: str, value: Any) -> Tuple[float, ...]:
        if hasattr(value, '__len__') and not isinstance(value, (str, bytes)) and not len(value):
            return ()
        try:
            return exact(name, value)
        except ConfigError:
            raise ConfigError(f'parameter {name} must be [] or a list of {length} numbers, '
                              f'got {value!r}') from None
    return read


def variances(name: str, value: Any) -> Tuple[float, ...]:
    values = numbers(6)(name, value)
    if min(values) < 0.0:
        raise ConfigError(f'parameter {name} must not contain negative variances')
    return values


def extra_models(name: str, value: Any) -> Tuple[Tuple[str, Tuple[float, float, float]], ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter {name} must be a list of strings, got {value!r}')
    models = []
    for entry in value:
        parts = entry.rsplit(None, 3)
        try:
            if len(parts) != 4:
                raise ValueError
            position = (float(parts[1]), float(parts[2]), float(parts[3]))
        except ValueError:
            raise ConfigError(f'parameter {name}: entry {entry!r} is not '
                              '"description x y z"') from None
        if not all(math.isfinite(p) for p in position):
            raise ConfigError(f'parameter {name}: entry {entry!r} has a non-finite position')
        models.append((parts[0], position))
    return tuple(models)


# A robot's name: its entity name, the first part of its parameters'
# names (robot_a.initial_pose) and, by default, its namespace and frame
# prefix, so it must be a valid ROS name token.
ROBOT_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*\Z')
_NAMESPACE = re.compile(r'/?(?:[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*)?\Z')


def robot_names(name: str, value: Any) -> Tuple[str, ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter {name} must be a list of robot names, got {value!r}')
    names = tuple(value)
    for robot in names:
        if not ROBOT_NAME.match(robot):
            raise ConfigError(f'parameter {name}: {robot!r} is not a robot name (a letter or _, '
                              'then letters, digits and _: it is also a namespace)')
    if len(set(names)) != len(names):
        raise ConfigError(f'parameter {name} lists a robot twice: {list(names)}')
    return names


# Names derived from a robot's namespace (its services' DDS topics) must stay
# within the middleware's 255 characters.
MAX_NAMESPACE_LENGTH = 150


def namespace(name: str, value: Any) -> str:
    """Read a ROS namespace: names of letters, digits and _ joined by /, absolute or not."""
    value = string(name, value)
    if len(value) > MAX_NAMESPACE_LENGTH:
        raise ConfigError(f'parameter {name} must be at most {MAX_NAMESPACE_LENGTH} '
                          f'characters long, got {len(value)}')
    if not _NAMESPACE.match(value) or value.endswith('/') and value != '/':
        raise ConfigError(f'parameter {name} must be a ROS namespace such as /robot1 or '
                          f'robot1 (letters, digits, _ and single / between names), got '
                          f'{value[:100]!r}')
    return value
