"""Every reader of vmt's text formats (plain UTF-8, docs/formats.md) says the same thing, in one
line, of a file that is not text: ``core.atomic.not_text_problem`` (a compressed file: which
compression and how to decompress it; else the first bad byte, counted from the file's start)."""

import gzip

import pytest

from core.exceptions import VmtError


def _keyreader(p):
    from core.exceptions import ConfigError
    from core.keyreader import read_text_file

    return read_text_file(p, ConfigError, "file")


def _positioning(p):
    from core.positioning import read_positioning_log

    return read_positioning_log(p)


def _probelog(p):
    from core.probelog import read_probe_log

    return read_probe_log(p)


def _recover(p):
    from hardware.campaign import recover_log

    return recover_log(p, None)  # the plan is looked at only once the file is text


READERS = {"keyreader": (_keyreader, ""), "positioning": (_positioning, ""), "probelog": (_probelog, ""),
           "recover_log": (_recover, "")}


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_file_that_is_not_text_is_refused_in_the_same_words_by_every_reader(tmp_path, reader):
    read, prefix = READERS[reader]
    body = b"setup,target,t_s\ns1,1,0\n"
    k = 20  # inside the data row
    bad = tmp_path / "bad.csv"
    bad.write_bytes(body[:k] + b"\xff" + body[k:])
    with pytest.raises(VmtError) as e:
        read(bad)
    assert str(e.value) == f"{prefix}{bad}: not UTF-8 text (invalid start byte at byte {k})"
    if reader != "keyreader" and reader != "recover_log":  # the readers that take a byte-order mark
        bad.write_bytes(b"\xef\xbb\xbf" + body[:k] + b"\xff" + body[k:])
        with pytest.raises(VmtError) as e:
            read(bad)
        assert str(e.value) == f"{prefix}{bad}: not UTF-8 text (invalid start byte at byte {k + 3})"
    packed = tmp_path / "log.csv"  # compressed, under a name that does not say so
    packed.write_bytes(gzip.compress(body))
    with pytest.raises(VmtError) as e:
        read(packed)
    assert str(e.value) == (f"{prefix}{packed}: gzip-compressed, not text: decompress it first "
                            f"(gzip -dc {packed} > {packed}.txt)")
