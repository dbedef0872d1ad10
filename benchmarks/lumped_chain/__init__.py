"""The lumped 1-D benchmark chain: its model, global baselines and cases (``foundation_scaling``, ``chain_frf``)."""
