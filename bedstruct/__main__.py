from bedstruct.cli import entry_point

entry_point()
