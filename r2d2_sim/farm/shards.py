"""
CI shards of a farm, by seed: ``--shard i/N`` runs the seeds whose hash falls to shard i.

A seed's shard is the SHA-256 of its decimal text, modulo N (shards counted
from 1, as pytest-split's ``--group``): it depends on the seed alone, never
on the order, the count of variations or the machine, so N jobs of a CI
matrix run every seed once between them, a rerun of one job runs the same
seeds, and a farm's shards line up with the same matrix's pytest-split
groups (``--splits N --group i``). Hashing, not ``seed % N``, spreads
seeds that share a pattern (every even seed, every tenth) over every shard.
Each shard writes its own report; ``python -m r2d2_sim.farm report`` merges
them.
"""

import hashlib
from typing import NamedTuple

__all__ = ['Shard', 'parse_shard', 'shard_of']


class Shard(NamedTuple):
    """Shard ``number`` (1..of) of ``of``."""

    number: int
    of: int

    def __str__(self) -> str:
        return f'{self.number}/{self.of}'

    def holds(self, seed: int) -> bool:
        """Return True when ``seed`` belongs to this shard."""
        return shard_of(seed, self.of) == self.number


def shard_of(seed: int, count: int) -> int:
    """Return the shard (1..count) of ``seed``."""
    digest = hashlib.sha256(str(int(seed)).encode('ascii')).digest()
    return int.from_bytes(digest[:8], 'big') % count + 1


def parse_shard(text: str) -> Shard:
    """Read ``i/N`` (1 <= i <= N); ValueError in one line for anything else."""
    index, slash, count = text.partition('/')
    try:
        shard = Shard(int(index), int(count))
    except ValueError:
        shard = None
    if not slash or shard is None:
        raise ValueError(f'--shard {text!r}: write it i/N, e.g. 1/4 (the first of four shards)')
    if shard.of < 1 or not 1 <= shard.number <= shard.of:
        raise ValueError(f'--shard {text}: i must be 1..N, counted from 1 (for N = '
                         f'{shard.of}: {"1" if shard.of == 1 else f"1..{shard.of}"})'
                         if shard.of >= 1 else f'--shard {text}: N must be 1 or more')
    return shard
