"""rrrobot_gym: simulator and RL environment for the RRRobot's legless locomotion."""
