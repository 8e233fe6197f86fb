"""Memory technology device (MTD) drivers: the FRAM that holds parameters and waypoints."""
