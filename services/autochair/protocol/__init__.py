"""Wire protocols, pure (bytes in, bytes out): shared by the services and the simulators."""
