"""The test harness: everything the test modules share, one module a concern.
No test module imports another; each imports what it needs from here (the
tests' folder is on sys.path: pytest puts it there, for tests/conftest.py).

Nothing is mocked: the helpers start real processes (YARP, ROS 1, ROS 2),
each in its own process group, on 127.0.0.1 with free ports and temporary
YARP / ROS folders, and stop them (SIGTERM, then SIGKILL of the whole group)
when a test is done; an ``atexit`` hook stops anything a crashed test left
behind. A test that needs missing middleware fails saying how to install it
(``scripts/setup.sh``); it is never skipped.

Middleware
    env         paths, the YARP installs of the test matrix and the active one,
                free ports, the environment of child processes
    procs       processes (Proc), peer scripts of tests/peers/ (Peer, Subscriber)
    yarp        yarpserver, YARP producer and reader peers, `yarp rpc`
    ros1        roscore, YARP's ROS 1 support (yarpserver --ros, type server), rospy peers
    ros2        ROS 2 domains, rclpy peers, /diagnostics, QoS
    jazzy       ROS 2 Jazzy: its venv, the environment of its processes, its rclpy peers
    netns       four hosts of network namespaces (tests/test_network.py)

Modules
    build       generated C++ built with CMake (ccache, one CMake project shared
                by the pytest-xdist workers under a file lock)
    generated   what a backend writes (the module apart from its runtime), the
                ybgc command, a generated module as a process
    module      a running module: its log, exit totals, clean exit, RPC stats
    launchers   how each backend's module is started (one Launcher a backend)
    differential    the native ROS 2 module and the rclpy node on the same streams
    services    commands: YARP RPC and rclpy service peers, a rig of modules of commands
    compose     a composed robot (examples/icub_robot): its producers, subscribers and checks
    variant     a second build of ybg_demo_msgs with one field more (one type name, two type hashes)
    cost        what one message costs each backend's module, in counts that do not depend
                on the machine's load (the cost guard, tests/test_cost.py; count_allocations.c)

Behaviour
    programs    the programs the tests run, and the configs each backend builds
    reference   what a module must output, for every backend, and the matcher
    geometry_reference   the converters' geometry, from scipy
    properties  hypothesis' profiles: ci (derandomized, the default), fuzz (scripts/fuzz.sh)
    behaviour, behaviour_values, behaviour_ros1
                the behaviour tests, written once, run on every backend

Documentation
    markdown    README.md and docs/*.md as the tests read them: sections, fenced
                blocks, the commands of shell blocks, tables
"""
