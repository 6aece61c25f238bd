"""Deterministic, independent random streams per (base seed, dataset, scenario, run, model)."""

from __future__ import annotations

import zlib

import numpy as np


def _tag(text: str) -> int:
    """Stable 32-bit number for a name (Python's hash() is salted per process)."""
    return zlib.crc32(text.encode("utf-8"))


def run_seed_sequence(seed: int, dataset: str, scenario: str, run: int) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(seed), _tag(dataset), _tag(scenario), int(run)])


def model_rng(sequence: np.random.SeedSequence, model: str) -> np.random.Generator:
    """A generator for one sub-model, so changing one model leaves the others' draws intact."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([*sequence.generate_state(4), _tag(model)])))
