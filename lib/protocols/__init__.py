"""Device wire-protocol codecs: bytes in, values out (docs/protocols.md)."""
