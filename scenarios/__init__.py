"""ctmm scenarios: one module per study (loaded as ``ctmm.scenarios``)."""
