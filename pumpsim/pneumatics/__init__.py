"""Gas, ports, valves, leaks, booster and motor (spec §8): the pump as the car sees it."""
