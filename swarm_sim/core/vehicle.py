"""The parts of one simulated autopilot, as its message handlers (`inbound.py`,
`commands.py`) and telemetry (`telemetry.py`) see them. `SimAutopilot` composes them;
each part owns its state:

    options, airframe, firmware   how the vehicle was started, what it is
    timeline                      simulated time, boot and delayed events
    out                           the messages to send, in order
    params                        the parameter table
    body, battery                 the airframe's kinematic state, its battery
    sensors                       booted, GPS, EKF position
    home                          the home position (and the EKF origin)
    stores                        mission, fence and rally items, their transfers,
                                  where AUTO is in the mission
    fence                         the loaded geofence and its breach state
    navigator                     the navigation task flown now, and the modes' tasks
    arming                        armed, pre-arm checks, crash, parachute
    mission                       AUTO: the mission run item by item
    modes                         the flight mode and its changes
    failsafes                     what the vehicle does on its own at a limit
    streams                       telemetry intervals (SET_MESSAGE_INTERVAL, ...)
    mount                         the camera mount, when there is a camera
"""

from __future__ import annotations

from collections import Counter
from typing import Protocol

from .airframes import AirframeParams
from .arming import Arming
from .battery import Battery
from .failsafes import Failsafes
from .fence import Fence
from .firmware import Firmware
from .geo import LocalFrame
from .home import HomeState
from .kinematics import Body
from .mission_runner import MissionRunner
from .modes import Modes
from .navigator import Navigator
from .options import SimOptions
from .outbox import Outbox
from .params import Parameters
from .payload import Mount
from .sensors import Sensors
from .stores import ItemStores
from .streams import StreamScheduler
from .timeline import Timeline


class Vehicle(Protocol):
    options: SimOptions
    airframe: AirframeParams
    firmware: Firmware
    sysid: int
    compid: int
    frame: LocalFrame
    counters: Counter[str]
    timeline: Timeline
    out: Outbox
    params: Parameters
    body: Body
    battery: Battery
    sensors: Sensors
    home: HomeState
    stores: ItemStores
    fence: Fence
    navigator: Navigator
    arming: Arming
    mission: MissionRunner
    modes: Modes
    failsafes: Failsafes
    streams: StreamScheduler
    mount: Mount | None
