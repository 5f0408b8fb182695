"""Entry point PlatformIO runs as its SCons: hands over to the PyPI scons package."""
import sys

import SCons.Script.Main

if __name__ == "__main__":
    sys.exit(SCons.Script.Main.main())
