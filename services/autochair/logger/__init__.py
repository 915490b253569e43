"""The logger: every logged key of keys.TOPICS recorded to MCAP (JSON + JSON Schema) with
Foxglove well-known channels derived alongside. Pure parts: schema (transcoding), foxglove
(derived channels), writer (MCAP files), reader (reading back, recovery); node = the process."""
