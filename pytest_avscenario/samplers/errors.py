"""The one error a sampler raises for a bad option, priority or told value."""


class SamplerError(ValueError):
    """A sampler was asked for by an unknown name or given options it does not take."""
