"""Body motion: skeleton, rotations, files, retargeting, procedural clips, body frame, features, windows."""
