import pytest


@pytest.fixture(scope="session")
def tiny_spread(tmp_path_factory):
    """One tiny two-layer blade spreading run shared by the spread tests."""
    from bedstruct.workflows import load_config, run_spread
    out = tmp_path_factory.mktemp("spread")
    cfg = load_config(preset="tiny")
    return cfg, run_spread(cfg, out=out), out
