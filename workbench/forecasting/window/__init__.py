"""The reference forecast (``model="window"``): a stepwise model fitted on the last
*train_blocks* blocks, Kalman trust set by hand (:mod:`.forecast` runs the steps)."""
