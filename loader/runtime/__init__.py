"""What runs every step from `set_ctrl`: the controller and its terms, in MuJoCo's stage order."""
