"""A recording carries the digest of what legsim logged (legsim.output.rrd.digest), and
``legsim replay`` refuses a recording that no longer matches it: a flipped byte gave other
samples, exit 0."""

from __future__ import annotations

import hashlib
import itertools
import json
import random
import re
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from helpers.reliability import run_cli
from legsim.errors import LegsimError
from legsim.output.rrd import digest as rrd_digest
from legsim.output.rrd import read_rrd, write_rrd
from legsim.output.rrd import write as rrd_write
from legsim.output.rrd.digest import Digest, check_file, feed_values
from legsim.output.trace import RecordingError
from legsim.scene import load_scene


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """The bouncing ball's recording over 0.5 s, and what reading it gives."""
    scene = load_scene("bouncing_ball", ["integrator.t_final=0.5"])
    path = tmp_path_factory.mktemp("ball") / "ball.rrd"
    write_rrd(scene.simulate(), scene, path)
    return path, read_rrd(path)


def flipped(path, tmp_path, position: int, bit: int = 0x40):
    damaged = tmp_path / "damaged.rrd"
    data = bytearray(path.read_bytes())
    data[position] ^= bit
    damaged.write_bytes(bytes(data))
    return damaged


def test_a_recording_written_by_legsim_is_verified(ball):
    _, data = ball
    assert data["verified"] is True


def flip_in_z(path, data, tmp_path):
    """``path`` with a bit flipped in the exponent of z at sample 100 (Rerun stores the numbers as
    they are, so the flip lands there)."""
    z = data["series"]["z"][1]
    position = path.read_bytes().find(np.float64(z[100]).tobytes())
    assert position > 0
    return flipped(path, tmp_path, position + 7)


def test_a_flipped_byte_in_a_sample_is_refused_before_rerun_reads_the_file(ball, tmp_path):
    path, data = ball
    damaged = flip_in_z(path, data, tmp_path)
    code, out, err = run_cli("replay", damaged)
    assert code == 2 and out == ""
    assert err.startswith(f"legsim: error: {damaged}: damaged legsim recording: its first ")
    assert err.endswith(" bytes no longer match the SHA-256 stored with them\n")


def test_without_the_files_seal_the_components_digest_names_what_differs(tmp_path, monkeypatch):
    # A recording a viewer received and saved holds no seal: the components' digest still holds.
    monkeypatch.setattr(rrd_write, "seal", lambda rec, path, entity: False)
    scene = load_scene("bouncing_ball", ["integrator.t_final=0.5"])
    path = write_rrd(scene.simulate(), scene, tmp_path / "unsealed.rrd")
    damaged = flip_in_z(path, read_rrd(path), tmp_path)
    code, _, err = run_cli("replay", damaged)
    assert code == 2
    assert err == (
        f"legsim: error: {damaged}: damaged legsim recording: /state/z:Scalars:scalars differs from what was logged "
        f"(the digest legsim stored with the data no longer matches)\n"
    )


def test_no_single_flipped_bit_gives_other_data_with_exit_0(ball, tmp_path):
    """200 flips at random positions: each recording is refused, or reads back exactly as the
    sound one (a flip in what legsim reads nothing of: Rerun's bookkeeping, the blueprint)."""
    path, sound = ball
    raw = path.read_bytes()
    rng = random.Random(7)
    refused = same = 0
    for _ in range(200):
        damaged = flipped(path, tmp_path, rng.randrange(len(raw)), 1 << rng.randrange(8))
        try:
            data = read_rrd(damaged)
        except LegsimError:
            refused += 1
            continue
        assert np.array_equal(data["times"], sound["times"]) and data["modes"] == sound["modes"]
        for name, (_, values) in sound["series"].items():
            assert np.array_equal(data["series"][name][1], values)
        assert data["meta"] == sound["meta"] and data["transitions"][0]["time"] == sound["transitions"][0]["time"]
        same += 1
    assert refused > 100 and refused + same == 200


def test_rerun_decodes_the_sealed_bytes_alone(ball, monkeypatch):
    """What follows the seal (its own message, the blueprint, Rerun's footer) is covered by no
    hash, and a flipped length there made Rerun's decoder abort the whole process (a panic in a
    thread of its own: a pytest worker died with it). The reader hands Rerun only the bytes the
    seal vouches for."""
    import rerun.chunk

    path, sound = ball
    opened = []
    real = rerun.chunk.RrdReader

    def reader(file):
        opened.append(Path(file).stat().st_size)
        return real(file)

    monkeypatch.setattr(rerun.chunk, "RrdReader", reader)
    data = read_rrd(path)
    assert opened == [check_file(path)] and opened[0] < path.stat().st_size
    assert np.array_equal(data["times"], sound["times"]) and data["verified"] is True


def test_a_temporary_folder_that_cannot_be_made_is_named_in_the_error(ball, monkeypatch, tmp_path):
    # The sealed bytes are copied for Rerun's reader: a temporary folder that cannot be made is
    # the reason given, not a damaged recording.
    import tempfile

    path, _ = ball
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "missing" / "folder"))
    with pytest.raises(RecordingError, match=r"cannot copy its sealed part to a temporary folder .*missing/folder"):
        read_rrd(path)


def test_a_flip_after_the_seal_reads_back_the_same_or_is_refused(ball, tmp_path):
    """300 flips spread over the bytes after the sealed part (the seal's message first: one of
    its flips aborted Rerun's decoder before): each reads back as the sound recording, or is
    refused (a flip in the seal's text)."""
    path, sound = ball
    raw = path.read_bytes()
    sealed = check_file(path)
    positions = np.linspace(sealed, len(raw) - 1, 300).astype(int)
    refused = 0
    for k, position in enumerate(positions):
        try:
            data = read_rrd(flipped(path, tmp_path, int(position), 1 << (k % 8)))
        except LegsimError:
            refused += 1
            continue
        assert np.array_equal(data["times"], sound["times"]) and data["meta"] == sound["meta"]
    assert refused < 10


def test_a_recording_without_a_digest_is_read_with_a_warning(tmp_path, monkeypatch):
    scene = load_scene("bouncing_ball", ["integrator.t_final=0.2"])
    monkeypatch.setattr(rrd_write, "DIGEST", "/legsim/not_a_digest")  # as an earlier legsim wrote it
    path = write_rrd(scene.simulate(), scene, tmp_path / "old.rrd")
    monkeypatch.undo()
    assert read_rrd(path)["verified"] is False
    code, _, err = run_cli("replay", path)
    assert code == 0
    assert err == (
        f"legsim: warning: {path} holds no digest of its data (written by an earlier legsim): a damaged file "
        f"cannot be told from a sound one\n"
    )


def test_a_digest_that_is_no_digest_is_refused(tmp_path, monkeypatch):
    scene = load_scene("bouncing_ball", ["integrator.t_final=0.2"])
    real = Digest.document
    monkeypatch.setattr(Digest, "document", lambda self: {**real(self), "digest": "0" * 64})
    path = write_rrd(scene.simulate(), scene, tmp_path / "x.rrd")
    with pytest.raises(RecordingError, match=r"the digest document does not match its own digest"):
        read_rrd(path)
    monkeypatch.setattr(Digest, "document", lambda self: [1, 2])
    path = write_rrd(scene.simulate(), scene, tmp_path / "y.rrd")
    with pytest.raises(RecordingError, match=r"its digest is unreadable: legsim/digest is an array"):
        read_rrd(path)


def test_the_streams_do_not_depend_on_how_rows_are_grouped():
    import pyarrow as pa

    rows = pa.array([[1.0, 2.0], [3.0], [], [4.0, 5.0, 6.0]], type=pa.list_(pa.float64()))
    whole, pieces = {}, {}
    feed_values(whole, rows)
    feed_values(pieces, rows.slice(0, 1))
    feed_values(pieces, rows.slice(1, 3).cast(pa.list_(pa.float32())))  # float32 holds these exactly
    assert {k: h.hexdigest() for k, h in whole.items()} == {k: h.hexdigest() for k, h in pieces.items()}
    other = {}
    feed_values(other, pa.array([[1.0], [2.0, 3.0], [], [4.0, 5.0, 6.0]], type=pa.list_(pa.float64())))
    assert other["values/lengths"].hexdigest() != whole["values/lengths"].hexdigest()


def test_the_digest_document_lists_every_entity_legsim_logged(ball):
    path, _ = ball
    from legsim.output.rrd.columns import read_columns

    document = json.loads(read_columns(path).values("/legsim/digest", "TextDocument:text")[0][0])
    assert {"/legsim/meta", "/legsim/samples", "/state/z", "/state/zd", "/mode", "/events/transitions"} <= set(
        document["entities"]
    )
    assert document["entities"]["/state/z"] == {
        "Scalars:scalars": document["entities"]["/state/z"]["Scalars:scalars"],
        "SeriesLines:names": document["entities"]["/state/z"]["SeriesLines:names"],
    }


def test_a_seal_whose_size_repeats_a_run_is_made_in_bounded_time():
    """The seal's bytes field is the same for every nonce. A size whose hex digits repeat a
    4-byte run (0x18a18a1: "18a1" twice) leaves no nonce that makes the text free of repeats, so
    the text is made from at most NONCE_TRIES nonces (a search until none repeats would never
    end): it still decodes to its size and SHA-256, and a size without a repeated run gets a
    text without one."""
    sha = hashlib.sha256(b"recording").hexdigest()
    counter = itertools.count()
    nonces = []

    def new_nonce():
        nonces.append(f"{next(counter):08x}")
        return nonces[-1]

    text = rrd_digest.seal_text(0x18A18A1, sha, new_nonce)
    assert len(nonces) == rrd_digest.NONCE_TRIES
    nonce, size, masked = re.fullmatch(rrd_digest._SEAL.pattern.decode(), text).groups()
    assert int(size, 16) == 0x18A18A1 and rrd_digest._masked(masked, nonce) == sha

    def repeats(text):
        return len({text[k : k + 4] for k in range(len(text) - 3)}) < len(text) - 3

    rng = random.Random(5)
    clean = rrd_digest.seal_text(0x2B7C0, sha, lambda: f"{rng.getrandbits(32):08x}")
    assert not repeats(clean)


def _seal_at(rng: random.Random, size: int, position: int, covered: int) -> tuple[bytes, str]:
    """``size`` random hex digits (no 'q' or 'z', so no seal of their own) with, written at
    ``position``, the seal of the first ``covered`` (<= ``position``) of them; and its SHA-256."""
    data = bytearray(rng.choice(b"0123456789abcdef") for _ in range(size))
    sha = hashlib.sha256(data[:covered]).hexdigest()
    text = rrd_digest.seal_text(covered, sha, lambda: f"{rng.getrandbits(32):08x}").encode("ascii")
    data[position : position + len(text)] = text
    return bytes(data), sha


def test_a_seal_across_two_read_blocks_is_found_where_it_lies(tmp_path, monkeypatch):
    """The search reads blocks from the file's end; a seal cut by a block's start is found
    whole in the block before it, at every cut, and a seal before ``start`` is not the writer's."""
    monkeypatch.setattr(rrd_digest, "_BLOCK", 256)
    rng = random.Random(11)
    path = tmp_path / "sealed.bin"
    for position in range(600, 780, 7):
        data, sha = _seal_at(rng, 1024, position, covered=position)
        path.write_bytes(data)
        assert rrd_digest._last_seal(path, len(data)) == (position, position, sha)
        assert rrd_digest._last_seal(path, len(data), start=position + 1) is None
    assert check_file(path) == position


def test_finding_the_seal_reads_one_block_at_a_time(tmp_path):
    """A recording's seal is near its end, but a writer whose seal LZ4 shortened searches the
    whole file for it: holding the file's bytes at once made a 3.5 MB recording's writer peak at
    4 MB, where a short one's peaks at 0.2 MB (``test_stream.py``). The peak is now one block's,
    about 64 kB, whatever the file's length."""
    data, sha = _seal_at(random.Random(3), 1 << 20, 0, covered=0)
    path = tmp_path / "long.bin"
    path.write_bytes(data * 4)
    tracemalloc.start()
    try:
        found = rrd_digest._last_seal(path, 4 * len(data), start=len(data))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert found == (3 * len(data), 0, sha)
    assert peak < 3 * rrd_digest._BLOCK, peak
