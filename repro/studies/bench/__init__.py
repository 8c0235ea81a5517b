"""Speed: the engines' decisions per second and the learner's seconds per epoch. Shared pieces:
``common``."""
