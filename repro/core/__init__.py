"""What the environments and everything above them stand on: errors, configs and scales, rollout
arrays, the event queue, the fixed-step clock, vector and PettingZoo wrappers, paths, a canvas."""
