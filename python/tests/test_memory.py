"""Worlds and vectors too large for the machine are refused with the figure before anything
is built, and a long build answers Ctrl-C."""

import re
import signal
import subprocess
import sys
import time

import pytest

import vpm_world


def test_a_million_environments_are_refused_with_their_memory():
    with pytest.raises(MemoryError) as error:
        vpm_world.VectorEnv(10**6, "open", n_agents=1, fov=1, channels="local")
    message = str(error.value)
    figures = re.search(r"1000000 environments of (\d+) bytes each .* world's (\d+) bytes "
                        r"would take about (\d+\.\d\d) GB", message)
    assert figures, message
    each, world, total = int(figures[1]), int(figures[2]), float(figures[3])
    # An environment holds at least its episode's penalty map (2,142 free cells, 4 bytes each)
    # and its observation; the open map's world and the total are what the parts add up to.
    assert 2_142 * 4 < each < 64_000 and world > 2_500, message
    assert total == round((10**6 * each + world) / 1e9, 2), message
    assert total > 17.18 and "max_memory=17179869184 (17.18 GB)" in message, message


def open_map(tmp_path, side):
    path = tmp_path / f"open{side}.txt"
    path.write_text(("." * side + "\n") * side)
    return str(path)


def test_a_world_whose_visibility_table_is_above_the_limit_is_refused(tmp_path):
    with pytest.raises(MemoryError) as error:
        vpm_world.World(open_map(tmp_path, 1000), fov=255, max_memory=10**9)
    message = str(error.value)
    assert "a 1000 x 1000 world with fov=255 (its visibility table) would take about 8.16 GB, " \
        "above max_memory=1000000000 (1.00 GB)" in message, message


def test_the_limit_is_the_callers_and_goes_with_a_pickled_copy():
    import pickle
    with pytest.raises(MemoryError):
        vpm_world.ParallelEnv("open", 2, max_memory=1000)
    env = vpm_world.ParallelEnv("open", 2, max_memory=None)
    assert pickle.loads(pickle.dumps(env.world)).width == 50
    vector = vpm_world.VectorEnv(2, "open", 2, max_memory=10**8)
    assert pickle.loads(pickle.dumps(vector)).n == 2


#: A world of minutes (L = 255 on a 1000 x 1000 map), built in a child that reports when it
#: starts; Python's own handler for Ctrl-C, which a shell's background job would ignore.
BUILD = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)
import vpm_world
print("building", flush=True)
start = time.monotonic()
try:
    vpm_world.World(sys.argv[1], fov=255)
    print("built")
except KeyboardInterrupt:
    print(f"interrupted after {time.monotonic() - start:.1f} s")
"""


def test_a_long_world_build_answers_ctrl_c(tmp_path):
    child = subprocess.Popen([sys.executable, "-c", BUILD, open_map(tmp_path, 1000)],
                             stdout=subprocess.PIPE, text=True)
    assert child.stdout.readline() == "building\n"
    time.sleep(1.0)
    child.send_signal(signal.SIGINT)
    try:
        out, _ = child.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()
        pytest.fail("the build went on for 30 s after Ctrl-C")
    assert out.startswith("interrupted after"), out
