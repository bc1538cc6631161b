"""The networks: mesh autoencoder, code space and quantiser, the window step, the direct baseline."""
