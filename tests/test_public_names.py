"""The package's public names: an old name (before the settings classes took one style) still
resolves, to the new class, with a DeprecationWarning naming the new name."""

import pytest

import hrr_garment


def test_an_old_public_name_gives_the_new_class_with_a_warning():
    with pytest.warns(DeprecationWarning, match="SimSettings"):
        old = hrr_garment.SimConfig
    assert old is hrr_garment.SimSettings
    with pytest.raises(AttributeError, match="NoSuchName"):
        hrr_garment.NoSuchName  # noqa: B018
