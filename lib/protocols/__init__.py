"""Device wire-protocol codecs: bytes in, values out (PROTOCOLS.md)."""
