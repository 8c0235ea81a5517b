"""Training one policy from the command line, and plotting the curves of run folders."""
