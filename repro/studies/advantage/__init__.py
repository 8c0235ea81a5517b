"""M-GAE against two other advantage estimators, bus and wildfire (X1)."""
