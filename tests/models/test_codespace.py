"""Code space model: quantiser, entropy, usage, decoding, the native window step, the expected code."""

import math

import numpy as np
import pytest
import torch

from hrr_garment.models.quantizer import GumbelQuantizer, group_entropy


@pytest.mark.parametrize("groups,classes,dim", [(4, 8, 3), (16, 2, 1), (64, 8, 8)])
def test_hard_codes_are_one_hot_and_gradients_flow_straight_through(groups, classes, dim):
    torch.manual_seed(0)
    q = GumbelQuantizer(groups, classes, dim).train()
    logits = torch.randn(5, groups * classes, requires_grad=True)
    codes, emb = q(logits, temperature=0.7)
    assert codes.shape == (5, groups, classes) and emb.shape == (5, groups * dim)
    assert torch.equal(codes.detach().sum(-1), torch.ones(5, groups))
    assert set(codes.detach().unique().tolist()) <= {0.0, 1.0}
    (emb * torch.randn_like(emb)).sum().backward()
    assert logits.grad is not None and torch.isfinite(logits.grad).all() and logits.grad.abs().sum() > 0
    assert q.embedding.grad is not None and q.embedding.grad.abs().sum() > 0
    q.eval()
    hard, _ = q(logits)
    assert torch.equal(hard.argmax(-1), q.split(logits).argmax(-1))  # eval: deterministic argmax


@pytest.mark.parametrize("classes", [2, 8, 16])
def test_entropy_of_one_hot_is_zero_and_of_uniform_is_log_k(classes):
    one_hot = torch.full((3, 5, classes), -1e4)
    one_hot[..., 1] = 0.0
    assert torch.allclose(group_entropy(one_hot), torch.zeros(3), atol=1e-6)
    assert torch.allclose(
        group_entropy(torch.zeros(3, 5, classes)), torch.full((3,), math.log(classes)), atol=1e-6
    )


def test_usage_counts_dead_classes_and_perplexity():
    q = GumbelQuantizer(2, 4, 1)
    usage = q.usage(torch.tensor([[0, 1], [1, 1], [2, 1], [3, 1]]))
    assert usage.dead == 3 and usage.total == 8  # group 1 only ever uses class 1
    assert usage.perplexity == pytest.approx((4 + 1) / 2)


@pytest.mark.parametrize(
    "body,material,clock", [(0, 0, 0), (3, 0, 0), (0, 5, 0), (3, 5, 0), (0, 5, 3), (0, 0, 2)]
)
def test_decoding_only_the_last_frame_equals_the_full_window(body, material, clock):
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceSettings

    torch.manual_seed(0)
    settings = CodeSpaceSettings(
        window=5,
        groups=4,
        classes=8,
        embedding_dim=3,
        hidden=32,
        motion_hidden=16,
        body_features=body,
        material_features=material,
        still_seconds=tuple(float(s + 1) for s in range(clock)),
        clock_conditions=bool(clock),
    )
    cs = CodeSpace(settings, settings.features, (6, 8))
    embedding = torch.randn(7, cs.quantizer.embedding_size)
    motion = torch.randn(7, 5, settings.features)
    condition = cs.condition_of(motion)
    c = clock + body + material  # the clock's columns are the memory's last, just before the body's
    assert settings.features - c == 124 + settings.memory.width - clock
    assert condition is None if not c else torch.equal(condition, motion[:, -1, -c:])
    with torch.no_grad():
        assert torch.allclose(
            cs.decode(embedding, True, condition),
            cs.decode(embedding, condition=condition)[:, -1:],
            atol=1e-6,
        )
        if c:  # the decoder reads the clock, the body and the cloth: another of any, other latents
            for column in range(c):
                other = condition.clone()
                other[:, column] += 1
                assert not torch.allclose(
                    cs.decode(embedding, condition=condition), cs.decode(embedding, condition=other)
                )
    with pytest.raises(ValueError, match="body and cloth values"):
        cs.decode(embedding, condition=None if c else torch.zeros(7, 2))


def test_settings_refuse_a_negative_or_fractional_condition_width():
    from hrr_garment.models.codespace import CodeSpaceSettings
    from hrr_garment.settings import SettingsError

    for bad in (-1, 2.5, True):
        with pytest.raises(SettingsError, match="material_features"):
            CodeSpaceSettings(material_features=bad)
    assert CodeSpaceSettings(body_features=12, material_features=5).condition_features == 17


@pytest.mark.native
@pytest.mark.parametrize(
    "window,hidden,heads,latent,condition",
    [
        (10, 32, 2, (6, 8), (0, 0, 0)),
        (7, 48, 3, (5, 3), (12, 5, 0)),
        (12, 64, 4, (9, 8), (0, 5, 0)),
        (7, 32, 2, (5, 3), (0, 5, 2)),
    ],
)
@pytest.mark.parametrize(
    "regression,last_frame,code",
    [(True, True, "expected"), (True, False, "expected"), (False, True, "expected"), (True, True, "argmax")],
)
def test_native_window_step_equals_pytorch_and_is_batch_invariant(
    window, hidden, heads, latent, condition, regression, last_frame, code
):
    """``condition``: (body measures, cloth values, stillness clock values) of a model across bodies
    or cloths, or whose decoder reads the clock, whose decoder reads the window's too."""
    from hrr_garment.models.codes import WindowCodes
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceSettings
    from hrr_garment.models.native_codes import native_window_codes

    torch.manual_seed(window)
    cfg = CodeSpaceSettings(
        window=window,
        groups=6,
        classes=5,
        embedding_dim=3,
        hidden=40,
        motion_hidden=hidden,
        attention_heads=heads,
        regression_code=code,
        body_features=condition[0],
        material_features=condition[1],
        still_seconds=tuple(float(s + 1) for s in range(condition[2])),
        clock_conditions=bool(condition[2]),
    )
    cs = CodeSpace(cfg, 124 + sum(condition), latent).eval()
    native = native_window_codes(cs, regression, last_frame)
    if native is None:
        pytest.skip("no C compiler: the native kernels are unavailable")
    windows = torch.randn(9, window, 124 + sum(condition))
    with torch.no_grad():
        want = WindowCodes(cs, regression, last_frame)(windows)
    got = native(windows)
    assert torch.allclose(got[0], want[0], atol=1e-5) and torch.equal(got[1], want[1])
    assert got[2].shape == want[2].shape and torch.allclose(got[2], want[2], atol=1e-5)
    one = native(windows[4:5])  # a stream's single window: the same bits as inside a batch
    assert all(torch.equal(a, b[4:5]) for a, b in zip(one[:2], got[:2]))
    assert not regression or torch.equal(one[2], got[2][4:5])
    # a stream's gates: each frame's computed as it came (one row, then all of one frame's rows
    # together), the windows' own bits; gates that are not these frames' change the result
    frames = windows.numpy()
    gates = np.stack(
        [
            np.concatenate([native.frame_gates(frames[:1, t]), native.frame_gates(frames[1:, t])])
            for t in range(window)
        ],
        1,
    )
    kept = native(windows, gates)
    assert all(torch.equal(a, b) for a, b in zip(kept, got))
    assert not torch.equal(native(windows, np.roll(gates, 1, axis=1))[0], got[0])
    with pytest.raises(ValueError, match="gates of shape"):
        native(windows, gates[:, 1:])


def test_the_expected_code_is_the_mean_embedding_under_each_groups_softmax():
    from hrr_garment.models.codes import regression_embedding
    from hrr_garment.models.codespace import CodeSpace, CodeSpaceSettings
    from hrr_garment.settings import SettingsError

    cs = {
        code: CodeSpace(
            CodeSpaceSettings(
                window=4,
                groups=3,
                classes=5,
                embedding_dim=2,
                hidden=8,
                motion_hidden=8,
                attention_heads=2,
                regression_code=code,
            ),
            124,
            (2, 2),
        )
        for code in ("expected", "argmax")
    }
    cs["argmax"].quantizer.embedding.data = cs["expected"].quantizer.embedding.data
    table = cs["expected"].quantizer.embedding.detach()  # (G, K, D)
    with torch.no_grad():
        uniform = regression_embedding(cs["expected"], torch.zeros(1, 3, 5))
        assert torch.allclose(
            uniform.reshape(3, 2), table.mean(1), atol=1e-6
        )  # every class equally likely: the mean
        peaked = torch.full((1, 3, 5), -50.0)
        peaked[0, [0, 1, 2], [4, 0, 2]] = 50.0  # certain codes: both kinds give the same classes' embeddings
        assert torch.allclose(
            regression_embedding(cs["expected"], peaked),
            regression_embedding(cs["argmax"], peaked),
            atol=1e-6,
        )
        logits = torch.randn(2, 3, 5)
        weights = torch.softmax(logits, -1)
        assert torch.allclose(
            regression_embedding(cs["expected"], logits).reshape(2, 3, 2),
            torch.einsum("bgk,gkd->bgd", weights, table),
            atol=1e-6,
        )
    with pytest.raises(SettingsError, match="regression_code"):
        CodeSpaceSettings(regression_code="mode")
    with pytest.raises(SettingsError, match="code space model: resonator damping"):
        CodeSpaceSettings(resonator_hz=(1.0,), resonator_damping=1.5)


def test_a_stillness_clock_widens_the_features_and_round_trips_through_the_settings():
    from hrr_garment.models.codespace import CodeSpaceSettings
    from hrr_garment.settings import SettingsError

    plain = CodeSpaceSettings()
    clocked = CodeSpaceSettings(still_seconds=(1.0, 3.0, 9.0))
    assert clocked.features == plain.features + 3 and clocked.memory.still_seconds == (1.0, 3.0, 9.0)
    assert "still_seconds" not in plain.to_dict()  # bundle.json as older versions read it
    assert CodeSpaceSettings.from_dict(clocked.to_dict()) == clocked
    # the clock as a condition of the garment encoder and the decoder: its columns counted in
    conditioned = CodeSpaceSettings(still_seconds=(1.0, 3.0, 9.0), clock_conditions=True, material_features=5)
    assert conditioned.condition_features == 8 and conditioned.features == clocked.features + 5
    assert "clock_conditions" not in clocked.to_dict()
    assert CodeSpaceSettings.from_dict(conditioned.to_dict()) == conditioned
    with pytest.raises(SettingsError, match="clock_conditions needs a stillness clock"):
        CodeSpaceSettings(clock_conditions=True)
    with pytest.raises(SettingsError, match="clock_conditions must be true or false"):
        CodeSpaceSettings(still_seconds=(1.0,), clock_conditions="yes")
    with pytest.raises(SettingsError, match="code space model: stillness time constants"):
        CodeSpaceSettings(still_seconds=(-1.0,))
    # held averages: 64 columns each, before the clock's (which stay the memory's last)
    held = CodeSpaceSettings(still_seconds=(1.0, 3.0, 9.0), held_seconds=(1.5,), clock_conditions=True)
    assert held.features == conditioned.features - 5 + 64 and held.memory.held_seconds == (1.5,)
    assert "held_seconds" not in clocked.to_dict()
    assert CodeSpaceSettings.from_dict(held.to_dict()) == held
    with pytest.raises(SettingsError, match="code space model: held time constants"):
        CodeSpaceSettings(held_seconds=(0.0,))
