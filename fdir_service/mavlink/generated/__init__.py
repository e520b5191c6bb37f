"""mavgen output for fdir.xml (do not edit; regenerate with `python -m fdir_service.mavlink.regenerate`)."""
