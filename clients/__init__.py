"""Programs that talk to the Gecko service over HTTP only."""
