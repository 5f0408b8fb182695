"""Host link to an AgNav robot (or a stock ArduPilot Rover) over MAVLink 2.

    Endpoint      transport + session: serial/USB/XBee, TCP, UDP; heartbeats, reconnect, tlog,
                  signing, telemetry budget; typed :class:`RobotState`
    AgnavRobot    AgNav commands: setpoints, e-stop, arm, behaviours, goal, params, calibration
    ArduRover     the same drive interface for a stock ArduPilot Rover (RC override or velocity)
    WireTable     calibration tables in the firmware's integer form
    FakeRobot     an in-process fake peer on 127.0.0.1 for tests
"""

from .calib_wire import TABLE_SPEED, TABLE_SPEED_RIGHT, TABLE_STEER, WireTable
from .endpoint import Endpoint, LinkDown, LinkTimeout, TELEMETRY_BUDGET_BYTES_S, parse_device
from .robot import AgnavRobot, CommandFailed
from .state import RobotState

__all__ = ["Endpoint", "LinkDown", "LinkTimeout", "TELEMETRY_BUDGET_BYTES_S", "parse_device", "AgnavRobot",
           "CommandFailed", "RobotState", "WireTable", "TABLE_STEER", "TABLE_SPEED", "TABLE_SPEED_RIGHT"]
