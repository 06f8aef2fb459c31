"""Drawing: scenes (footprints in their colours, an arrow for each heading), placements, tidying moves,
heatmaps, the demo figure and the learning curve (``plot.py``); every figure written atomically."""
