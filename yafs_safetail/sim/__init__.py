"""The only package that joins the YAFS core and the edge world: delay hooks, the selection that
drives any policy, placement, population, the runner and the Gymnasium environment."""
