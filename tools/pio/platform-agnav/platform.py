"""PlatformIO dev platform for AgNav: toolchains come from Debian, not the registry."""
from platformio.public import PlatformBase


class AgnavPlatform(PlatformBase):
    pass
