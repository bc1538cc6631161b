"""Training, one module per stage (autoencoder, codespace, baseline), and tau calibration."""
