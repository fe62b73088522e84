"""A replay back-end in another process, as a C++ or ROS 2 one would be run: each robot believes its
poses where they were first given (the dataset's dead reckoning) and, once a closure to another
robot is delivered, keeps that robot's pose at the closure's other end as first given, one message
of one pose on the link. Speaks docs/replay.md's JSON lines; argv[1]: "crash", "hang", "garbage",
"counts" to misbehave at the second checkpoint."""

import json
import sys
import time

mode = sys.argv[1] if len(sys.argv) > 1 else ""
start = json.loads(sys.stdin.readline())
links = {tuple(pair): k for k, pair in enumerate(start["links"])}
messages, sizes = [0] * len(links), [0] * len(links)
initial, own, kept = {}, {}, {}
seen = 0
for line in sys.stdin:
    request = json.loads(line)
    seen += 1
    if seen == 2 and mode == "crash":
        print("echo_backend: simulated crash", file=sys.stderr)
        sys.exit(3)
    if seen == 2 and mode == "hang":
        time.sleep(3600)
    if seen == 2 and mode == "garbage":
        print("this is not JSON", flush=True)
        continue
    for pose in request.get("poses", []):
        initial[pose["vertex"]] = pose["initial"]
        own[pose["vertex"]] = pose["initial"]
    for c in request.get("closures", []):
        for mine, other in ((c["robots"][0], c["to"]), (c["robots"][1], c["from"])):
            if other in initial:  # this robot receives the other end's pose from its robot
                kept[(mine, other)] = initial[other]
                k = links[tuple(sorted(c["robots"]))]
                messages[k] += 1
                sizes[k] += start["pose_bytes"]
    answer = {
        "own": [[v, *p] for v, p in sorted(own.items())],
        "kept": [[r, v, *p] for (r, v), p in sorted(kept.items())],
        "messages": messages if mode != "counts" or seen < 2 else messages[:-1],
        "bytes": sizes,
    }
    print(json.dumps(answer), flush=True)
