"""Hybrid inference: a motion in, an animated garment out (paper 3.5; docs/method.md).

Modules: :mod:`.animator` (the API: Animator), :mod:`.animation` (its result), :mod:`.stream`
(CrowdStream: many characters in one call; :mod:`.character_stream` one character; :mod:`.lod`
levels of detail), :mod:`.torch_crowd` (a crowd as one torch step on a GPU: :mod:`.torch_step`,
:mod:`.torch_push_out`), :mod:`.modes`, :mod:`.gate` (retrieval or regression per window),
:mod:`.blending` (windows to frames, inertialization), :mod:`.decoding` (the mesh decoder, the
denormal switch), :mod:`.collision` (push-out and strain limit; :mod:`.edge_limits` what they need
of a garment). The code-space step itself is :mod:`hrr_garment.models.codes`. The stages of a
frame, in one numbered list that the offline animator (:mod:`.clip_path`), the streams and the
torch step all run: :mod:`.frame_path`; what a run is asked: :mod:`.run_settings`.

Offline (default): features of the whole clip -> every window (stride 1, W frames, centred
coverage) -> motion encoder -> code distribution -> per window, retrieval from the database when
its entropy is below tau, else regression by the decoder -> per frame, the overlapping windows'
latents blended with weights that peak at window centres (sin^2, so a window fades in and out
smoothly and a change of source between windows is a cross-fade, continuous in position and
velocity) -> autoencoder decoder -> body frame to world -> collision push-out.

Causal (``causal=True``, and the streaming API): frame t sees only frames <= t. Its window is the
W frames ending at t (the clip's first frame repeated before the start); its garment latent is that
window's last frame. When the source changes (mode, or retrieved clip) the jump is removed by
inertialization: the jump between the old and the new source (in position and velocity) becomes an
offset that decays as a critically damped spring over about ``blend`` frames, so position and
velocity stay continuous; switches in quick succession add up and decay together. Streaming equals
offline causal.
"""
