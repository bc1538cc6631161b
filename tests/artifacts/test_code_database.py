"""The retrieval database (hrr_garment.artifacts.database.CodeDatabase): exact matches, Hamming search
equal to cosine on one-hot codes, excluding a sequence."""

import math

import numpy as np
import pytest

from hrr_garment.artifacts.database import CodeDatabase, code_similarity, pack_codes


@pytest.fixture
def database(rng):
    n, groups, classes = 300, 32, 8
    codes = rng.integers(0, classes, (n, groups))
    return CodeDatabase(codes, rng.normal(size=(n, 4, 3, 2)).astype(np.float32), np.arange(n) // 100,
                        np.arange(n) % 100, ["s0", "s1", "s2"], classes)


def test_database_returns_the_exact_match_for_a_training_window(database):
    idx, sim = database.search(database.codes[[5, 150, 299]])
    assert idx.tolist() == [5, 150, 299] and np.allclose(sim, 1.0)


def test_hamming_search_equals_cosine_on_one_hot_codes(database, rng):
    queries = rng.integers(0, 8, (40, 32))
    queries[:10] = database.codes[:10]
    queries[:10, :5] = (queries[:10, :5] + 1) % 8  # near misses
    idx, sim = database.search(queries)
    onehot = lambda c: np.eye(8)[c].reshape(len(c), -1) / math.sqrt(c.shape[1])  # noqa: E731
    cosine = onehot(queries) @ onehot(database.codes).T
    assert np.allclose(sim, cosine.max(1)) and np.allclose(cosine[np.arange(40), idx], cosine.max(1))
    assert np.allclose(code_similarity(queries, database.codes), cosine)
    assert pack_codes(queries, 8).shape == (40, 32)


def test_search_can_exclude_the_query_sequence(database):
    idx, _ = database.search(database.codes[[5, 150]], exclude=np.array([0, 1]))
    assert database.sequence[idx[0]] != 0 and database.sequence[idx[1]] != 1
