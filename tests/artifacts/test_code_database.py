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
    return CodeDatabase(
        codes,
        rng.normal(size=(n, 4, 3, 2)).astype(np.float32),
        np.arange(n) // 100,
        np.arange(n) % 100,
        ["s0", "s1", "s2"],
        classes,
    )


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


def test_among_equally_near_codes_retrieval_prefers_the_nearest_body():
    """Windows with the same code, simulated on three bodies (the last two motion columns): a query
    on a body retrieves the window of the body nearest it; a nearer code still wins over a nearer
    body; without bodies the lowest row wins as before."""
    from hrr_garment.artifacts.database import CodeDatabase

    codes = np.array([[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 0]], np.uint8)
    bodies = np.array([[-1.0, -1.0], [0.0, 0.0], [1.0, 1.2], [0.9, 1.0]], np.float32)
    motion = np.concatenate(
        [np.zeros((4, 3, 5), np.float32), np.repeat(bodies[:, None], 3, 1)], 2
    )  # (N, W, 7)
    db = CodeDatabase(
        codes,
        np.zeros((4, 3, 2, 2), np.float32),
        np.arange(4, dtype=np.int32),
        np.zeros(4, np.int32),
        ["a", "b", "c", "d"],
        classes=4,
        motion=motion,
    )
    query = np.array([[0, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3]], np.uint8)
    found, similarity = db.search(query, conditions=np.array([[0.1, -0.1], [0.9, 1.0], [-2.0, -2.0]]))
    assert found.tolist() == [1, 2, 0] and np.allclose(similarity, 1.0)  # row 3 is the nearest body, not code
    assert db.search(query)[0].tolist() == [0, 0, 0]
    found, _ = db.search(query[:1], exclude=np.array([1]), conditions=np.array([[0.1, -0.1]]))
    assert found.tolist() == [0]  # its own sequence excluded: the next nearest body among the equal codes
