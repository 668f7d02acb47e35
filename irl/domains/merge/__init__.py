"""The freeway-merge domain (paper section 4.2) as pure definitions: actions, states, bins, encounters, features, the MDP builder and the car-following logit."""
