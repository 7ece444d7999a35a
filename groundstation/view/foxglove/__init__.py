"""The run's live Foxglove server: channels, services, parameters, images and the history a late client gets."""
