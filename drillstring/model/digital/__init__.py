"""The digital controller: sensing, control law and top drive, compiled, on one block.

``layout`` names every entry of the block; ``lawcore`` the laws, ``drive`` the top drive,
``sense`` the sensing, ``block`` one sample of all three (the function every host calls),
``loop`` the sampled closed loop on the engine's kernel; ``controller`` the Python side
(:class:`~drillstring.model.digital.controller.DigitalController`). ``docs/controllers.md``
describes what they compute.
"""
