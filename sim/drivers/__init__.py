"""The drivers: the Policy protocol, the policy observation, and the learned, planning, IDM and callable drivers."""
