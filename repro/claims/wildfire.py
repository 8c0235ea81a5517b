"""C6-C9 and C11: the wildfire claims (checks arrive with the wildfire experiments)."""

from repro.claims import Claim

CLAIMS = [
    Claim("C6", "A long ED-trained policy holds at a fire with other interest 27% of the time, "
          "without 84%; picks closest/2nd/3rd fire 15/15/68%; closest cluster 98%",
          "27%, 84%, 15/15/68%, 98%", "within 10 percentage points", "make wildfire-behaviour"),
    Claim("C7", "The flowchart policy encoding C6 does 28% worse than the learned policy (ADR)",
          "28% worse", "flowchart ADR below learned ADR", "make wildfire-behaviour"),
    Claim("C8", "Policies trained on FS with dT <= 1 s transfer to ED as well as ED-trained ones; "
          "dT = 3.16 and 10 s degrade",
          "ED 2.780, FS-0.1 2.771, FS-0.316 2.745, FS-1 2.789, FS-3.16 2.212, FS-10 1.841",
          "ordering and overlap of CIs", "make fig-transfer"),
    Claim("C9", "FS-1 trained with T_health = 2.9999 degrades on ED", "1.937 vs 2.789",
          "FS-1(2.9999) well below FS-1(3.0)", "make fig-transfer"),
    Claim("C11", "Time-stepped compute grows ~N^2.2 while event-driven compute grows ~linearly",
          "argued, not measured", "fitted exponents ~2.2 and ~1", "make fig-scaling"),
]
