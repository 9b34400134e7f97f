"""The installed wheel against simulated probes: every read of every sensor
returns what the simulator holds (the Rust interpreter's values), a scan
names the probe, and each failure raises its own exception."""

import threading

import pytest

import yosemitech


def reads(sensor):
    return [c for c in sensor["commands"] if c["read"] and not c["trigger"]]


def test_sensors_describe_every_command_and_field():
    sensors = yosemitech.sensors()
    assert sensors, "the built-in spec has sensors"
    for sensor in sensors:
        assert sensor["name"] and sensor["title"]
        assert 1 <= sensor["default_address"] <= 247
        for command in sensor["commands"]:
            assert command["name"]
            for field in command["fields"]:
                assert field["name"]
                if field["min"] is not None and field["max"] is not None:
                    assert field["min"] <= field["max"]


def test_every_read_returns_what_the_probe_holds():
    for sensor in yosemitech.sensors():
        with yosemitech.Simulator(sensor["name"]) as sim:
            bus = yosemitech.Bus(sim.url, timeout=2.0)
            for command in reads(sensor):
                got = bus.read(sensor["name"], command["name"], sensor["default_address"])
                held = sim.values(command["name"])
                assert repr(got) == repr(held), (sensor["name"], command["name"])
                assert set(got) == {f["name"] for f in command["fields"]} or not command["fields"]


def test_a_scan_names_the_simulated_probe():
    for sensor in yosemitech.sensors():
        roles = {c["role"]: c for c in sensor["commands"] if c["role"]}
        serial = roles.get("serial_number")
        if serial is None or serial["fixed_address"] is not None:
            continue  # a scan asks each address for its serial number
        address = sensor["default_address"]
        with yosemitech.Simulator(sensor["name"]) as sim:
            found = yosemitech.Bus(sim.url, timeout=0.2).scan([address, address % 247 + 1])
        assert len(found) == 1, (sensor["name"], found)
        (device,) = found
        assert device["address"] == address
        assert device["sensor"] == sensor["name"] or sensor["name"] in device["candidates"], device
        if device["sensor"] is None:
            assert device["reason"], device


def test_silence_is_no_reply_and_names_the_command():
    sensor = yosemitech.sensors()[0]
    command = reads(sensor)[0]["name"]
    with yosemitech.Simulator(sensor["name"], address=1) as sim:
        bus = yosemitech.Bus(sim.url, timeout=0.1, retries=0)
        with pytest.raises(yosemitech.NoReply) as raised:
            bus.read(sensor["name"], command, 2)
    assert isinstance(raised.value, yosemitech.BusError)
    assert isinstance(raised.value, yosemitech.YosemitechError)
    assert command in str(raised.value)


def test_unknown_names_and_writes_are_refused_before_sending():
    sensor = yosemitech.sensors()[0]
    with yosemitech.Simulator(sensor["name"]) as sim:
        bus = yosemitech.Bus(sim.url, timeout=0.1, retries=0)
        with pytest.raises(yosemitech.UnknownError):
            bus.read("no_such_sensor", "get", 1)
        with pytest.raises(yosemitech.UnknownError):
            bus.read(sensor["name"], "no_such_command", 1)
        for s in yosemitech.sensors():
            for c in s["commands"]:
                if not c["read"]:
                    with pytest.raises(yosemitech.RequestError, match="is a write"):
                        bus.read(s["name"], c["name"], 1)


def test_a_malformed_spec_file_names_its_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("sensor:\n  name: [unclosed\n")
    with pytest.raises(yosemitech.SpecError) as raised:
        yosemitech.load_spec(bad)
    assert "bad.yaml:" in str(raised.value)


def test_reads_on_two_buses_run_in_threads():
    sensor = yosemitech.sensors()[0]
    command = reads(sensor)[0]["name"]
    errors = []

    def poll(url):
        try:
            bus = yosemitech.Bus(url)
            for _ in range(20):
                bus.read(sensor["name"], command, sensor["default_address"])
        except Exception as error:  # reported below
            errors.append(error)

    with yosemitech.Simulator(sensor["name"]) as a, yosemitech.Simulator(sensor["name"]) as b:
        threads = [threading.Thread(target=poll, args=(sim.url,)) for sim in (a, b)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=60)
    assert not errors, errors
    assert not any(t.is_alive() for t in threads)
