"""The forecast with memory (``model="memory"``): stepwise terms, coefficients over the
whole history with forgetting, noise levels from the data (:mod:`.forecast` runs the steps)."""
