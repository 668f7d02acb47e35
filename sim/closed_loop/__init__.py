"""The closed loop: the controller that hands lag cars A to a driver, its config, its control records and its actuation."""
