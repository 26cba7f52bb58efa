"""The three networks of the generator, each one config dataclass + one module, and their files.

- :mod:`.vqvae`: motion features <-> discrete tokens (causal VQ-VAE, EMA codebook).
- :mod:`.gpt`: the body GPT, next token from caption, path features and past tokens.
- :mod:`.controller`: the closed-loop GRU path controller (root x, z, heading per frame).
- :mod:`.path_features`: what the body GPT reads about the root path.
- :mod:`.normalizer`: the dataset feature statistics that travel with the VQ-VAE.
- :mod:`.checkpoint`: the self-describing checkpoint format shared by all three.
"""
