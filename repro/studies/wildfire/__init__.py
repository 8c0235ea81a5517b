"""The wildfire study (C6, C7): the evaluation of heuristic policies, the behaviour of a long
ED-trained policy against the flowchart, and the rendering of an episode."""
