"""C1-C5: the bus-holding claims (checks arrive with the bus experiments)."""

from repro.claims import Claim

CLAIMS = [
    Claim("C1", "PS-TRPO + M-GAE (MLP) beats Optimized Thresholds, which beats No Holding",
          "MLP > thresholds > no holding (Figs. bbtraining, bbtest)",
          "ordering holds with bootstrap CIs over seeds", "make fig-bus-lambda"),
    Claim("C2", "lambda changes the final return only slightly compared with the MLP-thresholds gap",
          "spread over lambda small (Fig. bbtraining)", "spread over lambda < gap MLP - thresholds",
          "make fig-bus-lambda"),
    Claim("C3", "smaller batches degrade convergence", "return after E epochs rises with batch size",
          "monotone in batch size", "make fig-bus-batch"),
    Claim("C4", "No Holding bunches the fleet: the leader saturates at L_max, the others run empty",
          "leader 4th-cycle loads 50, 64, 60, 75, ... and followers 0", "exact",
          "make fig-bus-load"),
    Claim("C5", "MLP reaches uniform arrivals in ~100 min, thresholds in ~200 min; MLP has lower "
          "load variance across buses", "~100 min vs ~200 min", "MLP faster and lower variance",
          "make fig-bus-arrivals"),
]
