"""How the claims are decided: the coverage of the interval kinds their verdicts rest on."""
