"""The generative decoder (models/sampler.py): flow matching learns a known conditional
distribution; a draw is reproducible by seed, causal, and the same drawn as a clip or as a crowd."""

import numpy as np
import pytest
import torch

from hrr_garment.models.sampler import ClothSampler, SamplerSettings, SampleTrack

FEATURES, LATENT = 3, 4


def _sampler(history: int = 1, hidden: int = 64) -> ClothSampler:
    torch.manual_seed(0)
    return ClothSampler(SamplerSettings(hidden=hidden, layers=2, history=history, steps=8), FEATURES, LATENT)


def test_flow_matching_learns_a_known_conditional_gaussian():
    """The departure given features f is N(A f, sigma^2) per value: after training, draws at a
    fixed f have that mean, and that spread once the flow is integrated finely; a few Euler steps
    draw narrower (their discretisation shrinks the spread)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # a tiny network: one thread is the fastest
    try:
        sampler = _sampler(history=0)
        a = torch.tensor([[1.0, -0.5, 0.0, 0.8], [0.0, 0.7, -1.0, 0.2], [0.5, 0.0, 0.3, -0.6]])
        sigma = torch.tensor([0.5, 0.8, 1.0, 0.6])
        gen = torch.Generator().manual_seed(1)
        opt = torch.optim.Adam(sampler.parameters(), lr=3e-3)
        schedule = torch.optim.lr_scheduler.CosineAnnealingLR(opt, 1200)
        zeros, no_history = torch.zeros(256, LATENT), torch.zeros(256, 0, LATENT)
        for _ in range(1200):
            f = torch.randn(256, FEATURES, generator=gen)
            target = f @ a + sigma * torch.randn(256, LATENT, generator=gen)
            noise, tau = torch.randn(256, LATENT, generator=gen), torch.rand(256, generator=gen)
            loss = sampler.flow_loss(sampler.context(f, zeros, zeros, no_history), target, noise, tau)
            opt.zero_grad()
            loss.backward()
            opt.step()
            schedule.step()
        f = torch.tensor([[0.5, -1.0, 1.0]]).repeat(4000, 1)
        zeros = torch.zeros(4000, LATENT)
        with torch.no_grad():
            context = sampler.context(f, zeros, zeros, torch.zeros(4000, 0, LATENT))
            noise = torch.randn(4000, LATENT, generator=gen)
            fine, few = sampler.draw(context, noise, steps=64), sampler.draw(context, noise, steps=4)
    finally:
        torch.set_num_threads(threads)
    expected = (f[:1] @ a)[0]
    assert torch.allclose(fine.mean(0), expected, atol=0.08), (fine.mean(0), expected)
    assert torch.allclose(fine.std(0), sigma, rtol=0.15), (fine.std(0), sigma)
    assert (few.std(0) < fine.std(0)).all()


def test_the_noise_moves_as_its_decay_says_and_stays_standard():
    """A track's noise: N(0, 1) at every frame (the first included), correlated 2a / (1 + a^2) from
    one frame to the next (two first-order filters of pole a)."""
    sampler = _sampler()
    track = SampleTrack(sampler, 3)
    noise = torch.stack([track.next_noise(0.9, 2000) for _ in range(60)])  # 2000 values, 60 frames
    assert abs(float(noise.std()) - 1.0) < 0.03 and abs(float(noise.mean())) < 0.03
    assert abs(float(noise[0].std()) - 1.0) < 0.05  # stationary from the first frame
    lag1 = float((noise[1:] * noise[:-1]).mean() / noise.square().mean())
    assert abs(lag1 - 2 * 0.9 / (1 + 0.81)) < 0.01


def test_mean_acceleration_counts_each_sequence_apart():
    """Vertices on a parabola x = t^2 / 2 (metres) accelerate 1 m per frame squared; a jump between
    two sequences laid end to end is not an acceleration."""
    from hrr_garment.train.sampler_calibration import mean_acceleration_mm

    t = np.arange(10.0)
    one = np.zeros((10, 5, 3))
    one[..., 0] = (t**2 / 2)[:, None]
    frames = np.concatenate([one, one + 100.0])
    assert mean_acceleration_mm(frames, [10, 10]) == pytest.approx(1000.0)
    assert mean_acceleration_mm(frames, [20]) > 2000.0


def test_a_draw_is_its_seeds_causal_and_the_same_as_a_crowd():
    sampler = _sampler(history=2, hidden=32).eval()
    sampler.noise_decay.fill_(0.9)
    rng = np.random.default_rng(0)
    features = torch.from_numpy(rng.standard_normal((30, FEATURES)).astype(np.float32))
    mean = torch.from_numpy(rng.standard_normal((30, LATENT)).astype(np.float32))
    a, again, other = (sampler.roll_out(features, mean, seed=seed) for seed in (5, 5, 6))
    assert torch.equal(a, again)  # bit for bit
    assert (a - other).abs().mean() > 0.1 * (a - mean).abs().mean()  # another seed, another draw
    head = sampler.roll_out(features[:12], mean[:12], seed=5)
    assert torch.equal(head, a[:12])  # frame t reads frames <= t only
    # two characters drawn together, frame by frame, as a crowd does: each its own clip's draw
    tracks = [SampleTrack(sampler, 5), SampleTrack(sampler, 6)]
    crowd = torch.stack(
        [
            sampler.draw_frame(tracks, features[t].repeat(2, 1), mean[t].repeat(2, 1), steps=8)
            for t in range(30)
        ],
        1,
    )
    assert torch.allclose(crowd[0], a, atol=1e-5) and torch.allclose(crowd[1], other, atol=1e-5)


def test_settings_are_checked():
    with pytest.raises(ValueError, match="history"):
        SamplerSettings.from_dict({"history": -1})
    with pytest.raises(ValueError, match="steps"):
        SamplerSettings.from_dict({"steps": 0})
    with pytest.raises(ValueError, match="unknown"):
        SamplerSettings.from_dict({"hiden": 3})
    for bad in ({"hidden": 10**9}, {"hidden": "wide"}, {"layers": True}, {"time_features": 2.5}):
        with pytest.raises(ValueError, match="whole number"):  # a bundle's settings come from outside
            SamplerSettings.from_dict(bad)
    sampler = _sampler()
    sampler.check_calibration()
    for name, value, said in (
        ("noise_decay", 1.0, "pole"),
        ("temperature", 0.0, "temperature"),
        ("temperature", float("inf"), "temperature"),
        ("residual_scale", -1.0, "scales"),
    ):
        broken = _sampler()
        getattr(broken, name).fill_(value)
        with pytest.raises(ValueError, match=said):
            broken.check_calibration()
