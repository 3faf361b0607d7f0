"""An independent implementation of spec §8 (gas, ports, valves, leaks, booster, DC motor) that writes bench logs with hidden changes for pumpsim identify/diagnose."""
