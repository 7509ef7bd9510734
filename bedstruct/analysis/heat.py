"""Heat conduction through the contact network of a powder bed.

Particles are nodes with heat capacity ``rho c V``; contacts are
conductances ``G = 2 k_s a`` from the contact radius (Batchelor & O'Brien
1977; Gusarov et al. 2003), optionally with a gas-gap term. A transient,
implicit, adaptive and energy-accounted solver (:func:`conduct_heat`) takes a
hemispherical heat source on the bed surface (held at a temperature, e.g. the
seed's 500 um / 1300 C pulse, or a constant power) and a plate that is
insulated or held at a temperature. The outputs are particle temperatures
over time, top-view temperature maps (:func:`temperature_map`), the shape of
the heat-affected zone (:func:`haz_shape`, roundness ``R = 4A / (pi L^2)``)
and the effective conductivity tensor of a region beside its contact fabric
(:func:`conductivity_tensor`).

Everything inside is SI (m, s, K, J, W); the frame's length unit is converted
once in :func:`thermal_network` and the conversion is recorded.

Examples
--------
>>> import numpy as np
>>> from bedstruct.core import Frame, Contacts, Units
>>> x = np.arange(5) * 19.6
>>> f = Frame(np.c_[x, np.zeros(5), np.zeros(5)], np.full(5, 10.0), box=[200, 50, 50], units=Units("micro"))
>>> c = Contacts(i=np.arange(4), j=np.arange(1, 5), branch=[[19.6, 0, 0]] * 4,
...              radii_i=[10.0] * 4, radii_j=[10.0] * 4)
>>> net = thermal_network(f, c)
>>> res = conduct_heat(net, t_end=0.05, initial_temperature=[1000.0, 300, 300, 300, 300])
>>> np.round(res.final_temperature, 1)  # equilibrated at the mean
array([440., 440., 440., 440., 440.])
"""

from ._heat_maps import (ConductivityTensor, HAZShape, TemperatureMap, conductivity_tensor,
                         haz_shape, haz_table, temperature_map)
from ._heat_network import COCR, GasGap, ThermalMaterial, ThermalNetwork, thermal_network
from ._heat_solver import EnergyRecord, HeatResult, HemisphereSource, conduct_heat, source_nodes

__all__ = [
    "ThermalMaterial", "COCR", "GasGap", "ThermalNetwork", "thermal_network",
    "HemisphereSource", "source_nodes", "EnergyRecord", "HeatResult", "conduct_heat",
    "TemperatureMap", "temperature_map", "HAZShape", "haz_shape", "haz_table",
    "ConductivityTensor", "conductivity_tensor",
]
