"""A person's motion as a model: the IMS generator, its Markov chain, its STFT and codebook."""
